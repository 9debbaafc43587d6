/* tests/test_cli.c: the wavetomo commands as a user runs them: the comparison report on the demo
 * system, the build → run chain, and clear refusals with non-zero exits. Uses $BIN/wavetomo (make test
 * builds it first). */
#include <fcntl.h>
#include <signal.h>
#include <stdarg.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/config/config.h"
#include "core/base/sha256.h"
#include "core/io/h5.h"
#include "testutil.h"

static char dir[64], wt[512];

static int run(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int run(const char *fmt, ...)
{
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    int n = snprintf(cmd, sizeof cmd, "%s ", wt);
    vsnprintf(cmd + n, sizeof cmd - n, fmt, ap);
    va_end(ap);
    /* stderr in the case's own directory: a fixed /tmp name is shared with every other `make test` running
     * on the machine (other worktrees, make debug-test), which made this suite flaky */
    size_t l = strlen(cmd);
    snprintf(cmd + l, sizeof cmd - l, " > /dev/null 2> %s/stderr.txt", dir);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static int stderr_has(const char *text)
{
    char path[128];
    snprintf(path, sizeof path, "%s/stderr.txt", dir);
    FILE *f = fopen(path, "r");
    char buf[8192] = {0};
    if (!f) return 0;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    return strstr(buf, text) != NULL;
}

static long file_size(const char *d, const char *name)
{
    char p[256];
    struct stat sb;
    snprintf(p, sizeof p, "%s/%s", d, name);
    return stat(p, &sb) == 0 ? (long)sb.st_size : -1;
}

/* The text of d/name into buf (at most size − 1 bytes, terminated); 0 when it cannot be opened. */
static int read_text(const char *d, const char *name, char *buf, size_t size)
{
    char p[256];
    snprintf(p, sizeof p, "%s/%s", d, name);
    FILE *f = fopen(p, "r");
    if (!f) return 0;
    const size_t n = fread(buf, 1, size - 1, f);
    fclose(f);
    buf[n] = 0;
    return 1;
}

static int is_png(const char *d, const char *name)
{
    char p[256];
    unsigned char sig[8] = {0};
    snprintf(p, sizeof p, "%s/%s", d, name);
    FILE *f = fopen(p, "rb");
    if (!f) return 0;
    size_t n = fread(sig, 1, 8, f);
    fclose(f);
    return n == 8 && !memcmp(sig, "\x89PNG\r\n\x1a\n", 8);
}

static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_cli_"); }
static void teardown(void) { tu_cli_teardown(dir); }

/* Start `wavetomo ARGS` (args[0] = the binary) with its stderr into a pipe whose read end is *rd. */
static pid_t spawn_stderr(const char *const *args, int *rd)
{
    int fd[2];
    ck_assert_int_eq(pipe(fd), 0);
    pid_t pid = fork();
    ck_assert(pid >= 0);
    if (pid == 0) {
        int nul = open("/dev/null", O_WRONLY);
        dup2(fd[1], 2), dup2(nul, 1), close(fd[0]);
        execv(wt, (char *const *)args);
        _exit(127);
    }
    close(fd[1]);
    *rd = fd[0];
    return pid;
}

/* sim interrupted in its loop: SIGTERM once the loop runs (the line before it read) ends the frame in hand and
 * writes RUN.h5 and TEL.h5 complete (readers accept them), with every per-frame dataset as long as `frames`, the
 * root attributes saying after how many of the requested frames and why, finite long-exposure figures; exit
 * 128 + 15 and one line saying so; no temporary left. */
START_TEST(test_sim_interrupt)
{
    char out[256], tel[256], line[1024], msg[1024] = "";
    snprintf(out, sizeof out, "%s/si.h5", dir);
    snprintf(tel, sizeof tel, "%s/sit.h5", dir);
    const char *args[] = {wt, "sim", "--config", "data/presets/demo.cfg", "--frames", "100000", "--out", out, "--telemetry", tel, NULL};
    int rd;
    pid_t pid = spawn_stderr(args, &rd);
    FILE *f = fdopen(rd, "r");
    int started = 0;
    while (!started && fgets(line, sizeof line, f)) started = strstr(line, "100000 frames, seed") != NULL;
    ck_assert_msg(started, "sim did not start its loop");
    usleep(300000); /* some frames past the settle window (20 frames of the demo) on an idle machine */
    ck_assert_int_eq(kill(pid, SIGTERM), 0);
    while (fgets(line, sizeof line, f))
        if (strstr(line, "stopped by")) snprintf(msg, sizeof msg, "%s", line);
    fclose(f);
    int status;
    ck_assert_int_eq(waitpid(pid, &status, 0), pid);
    ck_assert_msg(WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGTERM, "status %d", status);
    ck_assert_msg(strstr(msg, "stopped by SIGTERM after ") && strstr(msg, " of 100000 frames"), "message '%s'", msg);
    snprintf(line, sizeof line, "ls %s | grep -q 'tmp-'", dir);
    ck_assert_msg(system(line) != 0, "a temporary was left in %s", dir);

    wt_context *ctx = tu_context();
    wt_h5_reader *r = NULL;
    ck_assert_msg(wt_h5_open(ctx, out, &r) == WT_OK, "%s", wt_error_message(ctx));
    int64_t frames = 0, requested = 0, settle = 0;
    char *why = NULL;
    ck_assert_int_eq(wt_h5_read_int64(r, "frames", &frames), WT_OK);
    ck_assert_int_eq(wt_h5_read_int64(r, "settle_frames", &settle), WT_OK);
    ck_assert_int_eq(wt_h5_attr_read_int64(r, "/", "frames_requested", &requested), WT_OK);
    ck_assert_int_eq(wt_h5_attr_read_string(r, "/", "interrupted", &why), WT_OK);
    ck_assert_msg(frames >= 1 && frames < 100000 && requested == 100000, "%lld of %lld", (long long)frames,
                  (long long)requested);
    char want[128];
    snprintf(want, sizeof want, "SIGTERM after %lld of 100000 frames", (long long)frames);
    ck_assert_msg(strstr(why, want) && strstr(msg, want), "'%s' / '%s' lack '%s'", why, msg, want);
    free(why);
    double *se = malloc((size_t)frames * sizeof *se), le = -1.0;
    int64_t dims[1] = {frames};
    ck_assert_msg(wt_h5_read(r, "frame/strehl_field", WT_H5_F64, 1, dims, NULL, se, (size_t)frames) == WT_OK, "%s",
                  wt_error_message(ctx));
    for (int64_t t = 0; t < frames; t++) ck_assert_msg(se[t] > 0.0 && se[t] <= 1.0, "frame %lld: %g", (long long)t, se[t]);
    ck_assert_int_eq(wt_h5_read_double(r, "strehl_le_field", &le), WT_OK);
    if (frames > settle) ck_assert_msg(le > 0.0 && le <= 1.0, "LE Strehl %g over %lld frames", le, (long long)frames);
    free(se);
    wt_h5_close(r);
    ck_assert_msg(wt_h5_open(ctx, tel, &r) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_h5_attr_read_int64(r, "/", "frames_requested", &requested), WT_OK);
    ck_assert_int_eq(requested, 100000);
    wt_h5_close(r);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_did_you_mean)
{
    /* a misspelt command or option is refused (exit 2) with the nearest name: a dropped or doubled letter,
     * a transposition; a word far from every name gets no guess */
    ck_assert_int_eq(run("simm"), 2);
    ck_assert(stderr_has("unknown command 'simm' (did you mean 'sim'?)"));
    ck_assert_int_eq(run("comapre"), 2);
    ck_assert(stderr_has("(did you mean 'compare'?)"));
    ck_assert_int_eq(run("simulate-everything"), 2);
    ck_assert(!stderr_has("did you mean"));
    ck_assert_int_eq(run("sim data/presets/demo.cfg --frame 3"), 2);
    ck_assert(stderr_has("unknown option '--frame' (did you mean '--frames'?)"));
    ck_assert_int_eq(run("compare data/presets/demo.cfg --recno pcg3"), 2);
    ck_assert(stderr_has("(did you mean '--recon'?)"));
    ck_assert_int_eq(run("info --confg data/presets/demo.cfg"), 2);
    ck_assert(stderr_has("(did you mean '--config'?)"));
    ck_assert_int_eq(run("sim data/presets/demo.cfg --zzzzzzzzzz"), 2);
    ck_assert(stderr_has("unknown option '--zzzzzzzzzz'") && !stderr_has("did you mean"));
    /* a preset by its name, from any directory; a misspelt one refused with the nearest name */
    ck_assert_int_eq(run("info demo --no-nnz"), 0);
    ck_assert_int_eq(run("info eelt-mcao.cfg --no-nnz"), 0);
    ck_assert_int_ne(run("info demoo"), 0);
    ck_assert(stderr_has("nor a preset of that name (did you mean 'demo'?)"));
    /* a bad value of a sweep is named as the user wrote it, before any case runs */
    ck_assert_int_ne(run("compare data/presets/demo.cfg --recon pcg3 --frames 30 --sweep recon.alpha=0.5,abc --out %s/sw",
                         dir), 0);
    ck_assert(stderr_has("--sweep recon.alpha: value 2 ('abc')") && !stderr_has("--set"));
}
END_TEST

/* θ0 of r0 [m] over n layers at h [m] with fractions f, up to the constant 0.314 / arcsec (the ratio is tested) */
static double theta0_shape(double r0, int n, const double *h, const double *f)
{
    double s = 0.0;
    for (int k = 0; k < n; k++) s += f[k] * pow(h[k], 5.0 / 3.0);
    return r0 / pow(s, 3.0 / 5.0);
}

START_TEST(test_compare_learned_report)
{
    /* issue 35: a sweep over the model's source draws the run, each model against the oracle and the learned
     * atmosphere (learned_1.png, with the layers' winds; the oracle estimates nothing: no learned_0.png); the report's
     * table states the estimate of results.h5 against the configured truth (demo.cfg: r0 and its five layers), to
     * its print rounding */
    char out[128];
    snprintf(out, sizeof out, "%s/learned", dir);
    ck_assert_int_eq(run("compare --config data/presets/demo-learned.cfg --recon pcg3 --frames 220 --sweep "
                         "'recon.atmosphere.source=\"oracle\",\"learned\"' --set 'recon.atmosphere.learn_wind=\"aligned\"' "
                         "--out %s --quiet", out), 0);
    const char *pngs[] = {"wfe_over_run.png", "wfe_minus_oracle.png", "learned_1.png"};
    for (int i = 0; i < 3; i++) ck_assert_msg(is_png(out, pngs[i]) && file_size(out, pngs[i]) > 2000, "%s", pngs[i]);
    ck_assert_int_lt(file_size(out, "learned_0.png"), 0);
    static char text[200000];
    ck_assert(read_text(out, "report.md", text, sizeof text));
    ck_assert_ptr_nonnull(strstr(text, "## The learned atmosphere"));
    ck_assert_ptr_nonnull(strstr(text, "(learned_1.png)"));
    const char *row = strstr(text, "| pcg3 | \"learned\" | 1 |");
    ck_assert_msg(row, "no table row of pcg3's one estimate");
    double er = NAN, et = NAN, ev = NAN;
    ck_assert_int_eq(sscanf(row, "| pcg3 | \"learned\" | 1 | %lf %% / %*f %% | %lf %% / %*f %% | %lf %%", &er, &et, &ev), 3);
    ck_assert(isfinite(ev)); /* the layers' winds learned: their v̄ against the oracle's (the plot's third panel) */

    wt_context *ctx = tu_context();
    wt_config *cfg = NULL;
    ck_assert_msg(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg) == WT_OK, "%s", wt_error_message(ctx));
    wt_h5_reader *r;
    char p[256];
    snprintf(p, sizeof p, "%s/results.h5", out);
    ck_assert_msg(wt_h5_open(ctx, p, &r) == WT_OK, "%s", wt_error_message(ctx));
    int rank = 0;
    int64_t dims[WT_H5_MAX_RANK] = {0}, one[1] = {1};
    ck_assert_int_eq(wt_h5_dims(r, "learned/pcg3_1/seed0/altitude", &rank, dims), WT_OK);
    const int na = (int)dims[0];
    ck_assert(rank == 1 && na > 2 && na <= 64);
    double r0, alt[64], frac[64];
    int64_t d2[2] = {1, na};
    ck_assert_int_eq(wt_h5_read(r, "learned/pcg3_1/seed0/r0", WT_H5_F64, 1, one, NULL, &r0, 1), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "learned/pcg3_1/seed0/altitude", WT_H5_F64, 1, dims, NULL, alt, (size_t)na), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "learned/pcg3_1/seed0/fraction", WT_H5_F64, 2, d2, NULL, frac, (size_t)na), WT_OK);
    wt_h5_close(r);
    const double want_r = 100.0 * (r0 / cfg->r0 - 1.0),
                 want_t = 100.0 * (theta0_shape(r0, na, alt, frac) /
                                   theta0_shape(cfg->r0, cfg->nlayers, cfg->layer_altitude, cfg->layer_fraction) - 1.0);
    ck_assert_msg(fabs(er - want_r) <= 0.051 && fabs(et - want_t) <= 0.051, "table r0 %+.1f %%, θ0 %+.1f %%; results.h5 "
                  "against the truth %+.3f %%, %+.3f %%", er, et, want_r, want_t);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

START_TEST(test_compare_writes_the_report)
{
    /* issue #4: compare on the demo preset writes every file of the report; the plots are non-empty PNGs */
    char out[128];
    snprintf(out, sizeof out, "%s/cmp/nested", dir); /* parents are created like mkdir -p */
    ck_assert_int_eq(run("compare --config data/presets/demo.cfg --recon mvm,pcg3,cg9 --sweep lgs.wfs.photons=50,100 "
                         "--frames 40 --out %s --quiet",
                         out),
                     0);
    const char *files[] = {"results.h5", "summary.csv", "report.md"};
    for (int i = 0; i < 3; i++) ck_assert_msg(file_size(out, files[i]) > 100, "%s missing or empty", files[i]);
    const char *pngs[] = {"strehl_vs_sweep.png", "time_per_frame.png", "map_mvm_0.png", "map_pcg3_0.png", "map_cg9_0.png",
                          "map_mvm_1.png", "map_pcg3_1.png", "map_cg9_1.png"};
    for (int i = 0; i < 8; i++) {
        ck_assert_msg(is_png(out, pngs[i]), "%s is not a PNG", pngs[i]);
        ck_assert_msg(file_size(out, pngs[i]) > 2000, "%s is (nearly) empty", pngs[i]);
    }
    /* each method's WFE minus the first method's over the field, per sweep value, linked from report.md; none of the
     * first against itself */
    const char *diffs[] = {"diff_pcg3_mvm_0.png", "diff_cg9_mvm_0.png", "diff_pcg3_mvm_1.png", "diff_cg9_mvm_1.png"};
    for (int i = 0; i < 4; i++) ck_assert_msg(is_png(out, diffs[i]) && file_size(out, diffs[i]) > 2000, "%s", diffs[i]);
    ck_assert_int_lt(file_size(out, "diff_mvm_mvm_0.png"), 0);
    char grep[1024];
    snprintf(grep, sizeof grep, "grep -q '## Differences between methods' %1$s/report.md && grep -q '(diff_cg9_mvm_1.png)' "
             "%1$s/report.md && grep -q '| method | lgs.wfs.photons |' %1$s/report.md", out);
    ck_assert_msg(system(grep) == 0, "report.md lacks the differences or the sweep column");
    /* summary.csv: a header and one row per method and sweep value */
    char p[256], line[512];
    snprintf(p, sizeof p, "%s/summary.csv", out);
    FILE *f = fopen(p, "r");
    ck_assert_ptr_nonnull(f);
    int rows = 0;
    while (fgets(line, sizeof line, f)) rows++;
    fclose(f);
    ck_assert_int_eq(rows, 1 + 3 * 2);
    /* results.h5: [method, sweep value, direction] and [method, sweep value, part] */
    wt_context *ctx = tu_context();
    wt_h5_reader *r;
    snprintf(p, sizeof p, "%s/results.h5", out);
    ck_assert_msg(wt_h5_open(ctx, p, &r) == WT_OK, "%s", wt_error_message(ctx));
    int64_t e1[3] = {3, 2, 25}, e2[3] = {3, 2, 6}, e3[2] = {3, 2};
    ck_assert_msg(wt_h5_check_shape(r, "strehl_le", 3, e1, NULL) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_h5_check_shape(r, "time_parts", 3, e2, NULL) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_msg(wt_h5_check_shape(r, "strehl_le_field", 2, e3, NULL) == WT_OK, "%s", wt_error_message(ctx));
    double fs[6];
    ck_assert_int_eq(wt_h5_read(r, "strehl_le_field", WT_H5_F64, 2, e3, NULL, fs, 6), WT_OK);
    for (int i = 0; i < 6; i++) ck_assert(fs[i] > 0.0 && fs[i] < 1.0);
    wt_h5_close(r);
    wt_context_free(ctx);
    /* a second run reuses the cached MVM (same hash) */
    ck_assert_int_eq(run("compare --config data/presets/demo.cfg --recon mvm --frames 20 --sweep lgs.wfs.photons=50 "
                         "--out %s",
                         out),
                     0);
    ck_assert(stderr_has("mvm from the cache"));
}
END_TEST

START_TEST(test_build_run_chain_and_refusals)
{
    char tel[128], mat[128], cmd[128];
    snprintf(tel, sizeof tel, "%s/tel.h5", dir);
    snprintf(mat, sizeof mat, "%s/M.h5", dir);
    snprintf(cmd, sizeof cmd, "%s/c.h5", dir);
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --frames 12 --out %s/r.h5 --telemetry %s", dir, tel), 0);
    ck_assert_int_eq(run("build --config data/presets/demo.cfg --out %s", mat), 0);
    ck_assert_int_eq(run("run --matrix %s --telemetry %s --out %s", mat, tel, cmd), 0);
    ck_assert_int_eq(run("run --recon pcg3 --telemetry %s --out %s/c2.h5", tel, dir), 0);
    /* a matrix from another configuration is refused by run and by sim */
    ck_assert_int_eq(run("build --config data/presets/demo.cfg --set recon.alpha=3.0 --out %s/M3.h5", dir), 0);
    ck_assert_int_ne(run("run --matrix %s/M3.h5 --telemetry %s --out %s/c3.h5", dir, tel, dir), 0);
    ck_assert(stderr_has("built for another system"));
    ck_assert(stderr_has("recon.alpha = 3.0 in the matrix, 1.0 in ")); /* the key that differs, both values */
    ck_assert_int_ne(run("sim --config data/presets/demo.cfg --recon mvm --matrix %s/M3.h5 --out %s/r3.h5", dir, dir), 0);
    ck_assert(stderr_has("built for another system"));
    ck_assert(stderr_has("recon.alpha = 3.0 in the matrix, 1.0 in data/presets/demo.cfg"));
    /* a matrix built without prediction is another system for a predicting loop (the shift is inside a predictive R) */
    ck_assert_int_ne(run("sim --config data/presets/demo.cfg --recon mvm --matrix %s --set recon.predict=true --frames 12 "
                         "--out %s/rp.h5", mat, dir), 0);
    ck_assert(stderr_has("built for another system"));
    ck_assert(stderr_has("atmosphere.wind_speed_mps = not set in the matrix")); /* the wind is a predictive R's */
    /* and the integrator on the layers is the matrix-free reconstructors': refused for the MVM, named */
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --recon mvm --matrix %s --set recon.predict=true --set "
                         "'recon.predict_integrator=\"layers\"' --frames 12 --out %s/rp.h5", mat, dir), 1);
    ck_assert(stderr_has("key 'recon.predict_integrator' = \"layers\": the MVM has no layers"));
    ck_assert_int_ne(run("sim --config data/presets/demo.cfg --set recon.predict=maybe --out %s/rq.h5", dir), 0);
    ck_assert(stderr_has("recon.predict"));
    ck_assert_int_ne(run("sim --config data/presets/demo.cfg --set recon.predict=true --set recon.predict_lead_frames=-1.0 "
                         "--out %s/rq.h5", dir), 0);
    ck_assert(stderr_has("recon.predict_lead_frames"));
    ck_assert_int_ne(run("sim --config data/presets/demo-diffractive.cfg --set 'lgs.wfs.reference_seeing=\"blurred\"' "
                         "--out %s/rs.h5", dir), 0);
    ck_assert(stderr_has("lgs.wfs.reference_seeing") && stderr_has("tilt_removed"));
    /* telemetry and --config of two systems: the key named too */
    ck_assert_int_ne(run("run --recon pcg3 --config data/presets/demo.cfg --set lgs.wfs.photons=50 --telemetry %s "
                         "--out %s/c4.h5", tel, dir), 0);
    ck_assert(stderr_has("lgs.wfs.photons = 100.0 in"));
    /* an output that cannot be written is found before the run */
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --out /nonexistent-dir/r.h5"), 1);
    ck_assert(stderr_has("/nonexistent-dir"));
    /* usage errors exit 2, config errors 1, with the key named */
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --frames abc --out %s/x.h5", dir), 2);
    ck_assert_int_eq(run("info data/presets/demo.cfg --set loop.gain=1.5"), 1);
    ck_assert(stderr_has("loop.gain"));
    /* info says which reconstructor runs its operator in single precision (the E-ELT preset's pcg3), and only it */
    ck_assert_int_eq(run("info data/presets/eelt-mcao.cfg --no-nnz | grep -q 'pcg3: .*operator in single precision'"), 0);
    ck_assert_int_eq(run("info data/presets/eelt-mcao.cfg --no-nnz | grep -q 'cg9: .*operator in single precision'"), 1);
    ck_assert_int_eq(run("compare --config data/presets/demo.cfg --recon mvm,foo --out %s/z", dir), 2);
    ck_assert(stderr_has("foo"));
    /* every command answers --help */
    const char *cmds[] = {"info", "sim", "build", "run", "compare", "bench", "budget", "wisdom"};
    for (int i = 0; i < 8; i++) ck_assert_int_eq(run("%s --help", cmds[i]), 0);
    /* bench has no resource estimate: --dry-run is refused, not ignored */
    ck_assert_int_eq(run("bench data/presets/demo.cfg --dry-run"), 2);
    ck_assert(stderr_has("--dry-run"));
    /* every command takes CONFIG as a plain word or as --config, and refuses a second one (positional or
     * --config), naming both (wt_cli_config_arg) */
    const char *one[] = {"info", "bench", "wisdom", "sim", "build", "compare", "budget", "run"};
    for (int i = 0; i < 8; i++) {
        ck_assert_int_eq(run("%s data/presets/demo.cfg data/presets/eelt-mcao.cfg --out %s/w", one[i], dir), 2);
        ck_assert(stderr_has("more than one CONFIG"));
        ck_assert(stderr_has("eelt-mcao.cfg"));
        ck_assert_int_eq(run("%s --config data/presets/demo.cfg --config data/presets/eelt-mcao.cfg --out %s/w", one[i],
                             dir), 2);
        ck_assert(stderr_has("more than one CONFIG"));
    }
    /* the estimate from either form (bench has none: its cheapest run instead) */
    const char *est[] = {"info", "wisdom", "sim", "build", "compare", "budget"};
    for (int i = 0; i < 6; i++)
        for (int form = 0; form < 2; form++) {
            char out[128] = "--no-nnz"; /* info writes nothing */
            if (i) snprintf(out, sizeof out, "--out %s/e%d", dir, i);
            ck_assert_msg(run("%s %sdata/presets/demo.cfg --dry-run %s", est[i], form ? "--config " : "", out) == 0,
                          "%s with CONFIG %s", est[i], form ? "by --config" : "positional");
            ck_assert(!stderr_has("error"));
        }
    ck_assert_int_eq(run("run --recon pcg3 --telemetry %s data/presets/demo.cfg --out %s/c5.h5", tel, dir), 0);
    ck_assert_int_eq(run("bench --config data/presets/demo.cfg --no-loop --no-build --reps 3"), 0);
}
END_TEST

/* A telemetry file whose frame 2 holds a NaN slope, and one whose frames have the wrong length: both are
 * refused by `wavetomo run`, naming the frame or the shape. */
static void write_telemetry(const char *path, const char *config_text, int64_t nslopes, int64_t nact, int nan_frame)
{
    wt_context *ctx = tu_context();
    wt_h5_writer *w;
    wt_h5_series *s, *so, *c;
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_int_eq(wt_h5_write_string(w, "config", config_text, "configuration"), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "slopes", WT_H5_F32, nslopes, "rad", "slopes", &s), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "slopes_ol", WT_H5_F32, nslopes, "rad", "slopes", &so), WT_OK);
    ck_assert_int_eq(wt_h5_series_create(w, "commands", WT_H5_F32, nact, "m", "commands", &c), WT_OK);
    float *buf = calloc((size_t)(nslopes > nact ? nslopes : nact), sizeof *buf);
    for (int t = 0; t < 4; t++) {
        for (int64_t i = 0; i < nslopes; i++) buf[i] = 1e-7f * (float)((i + t) % 13);
        if (t == nan_frame) buf[5] = NAN;
        ck_assert_int_eq(wt_h5_series_append(s, WT_H5_F32, buf), WT_OK);
        ck_assert_int_eq(wt_h5_series_append(so, WT_H5_F32, buf), WT_OK);
        memset(buf, 0, (size_t)nact * sizeof *buf);
        ck_assert_int_eq(wt_h5_series_append(c, WT_H5_F32, buf), WT_OK);
    }
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
    free(buf);
    wt_context_free(ctx);
}

START_TEST(test_run_rejects_bad_frames)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    const int64_t nslopes = 1548, nact = 759; /* the demo system (wavetomo info; 571 without the guard ring) */
    char nanp[128], widep[128], mat[128];
    snprintf(nanp, sizeof nanp, "%s/nan.h5", dir);
    snprintf(widep, sizeof widep, "%s/wide.h5", dir);
    snprintf(mat, sizeof mat, "%s/M.h5", dir);
    write_telemetry(nanp, cfg->canonical, nslopes, nact, 2);
    write_telemetry(widep, cfg->canonical, nslopes + 1, nact, -1);
    ck_assert_int_eq(run("run --recon pcg3 --telemetry %s --out %s/o1.h5", nanp, dir), 1);
    ck_assert(stderr_has("frame 2"));
    ck_assert(stderr_has("NaN"));
    ck_assert_int_eq(run("build --config data/presets/demo.cfg --out %s", mat), 0);
    ck_assert_int_eq(run("run --matrix %s --telemetry %s --out %s/o2.h5", mat, nanp, dir), 1);
    ck_assert(stderr_has("frame 2"));
    ck_assert_int_eq(run("run --matrix %s --telemetry %s --out %s/o3.h5", mat, widep, dir), 1);
    ck_assert(stderr_has("1549"));
    ck_assert(stderr_has("expected"));
    /* nothing half-written at the refused outputs */
    char o[160];
    snprintf(o, sizeof o, "%s/o1.h5", dir);
    ck_assert_int_ne(access(o, F_OK), 0);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The PNG's width and height from its IHDR (0 when not a PNG). */
static void png_size(const char *d, const char *name, unsigned *w, unsigned *h)
{
    char p[256];
    unsigned char b[24] = {0};
    snprintf(p, sizeof p, "%s/%s", d, name);
    FILE *f = fopen(p, "rb");
    *w = *h = 0;
    if (!f) return;
    if (fread(b, 1, 24, f) == 24 && !memcmp(b, "\x89PNG\r\n\x1a\n", 8) && !memcmp(b + 12, "IHDR", 4)) {
        *w = (unsigned)b[16] << 24 | (unsigned)b[17] << 16 | (unsigned)b[18] << 8 | b[19];
        *h = (unsigned)b[20] << 24 | (unsigned)b[21] << 16 | (unsigned)b[22] << 8 | b[23];
    }
    fclose(f);
}

/* issue 19 item 7: `info --spots DIR` draws the first diffractive LGS; a geometric system is refused with
 * nothing left behind; the compare report of a diffractive system links the same pictures. */
/* `wavetomo wisdom` writes FFTW wisdom that a run then plans from (recorded in its output's configuration with the
 * file's SHA-256); a wisdom without a size the run needs is refused naming the key and the size; no --out is a
 * usage error, a configuration without a full-prior variant a refusal, and an existing file that is not
 * wisdom is not replaced. */
START_TEST(test_wisdom_command)
{
    char w[128], w16[128], h5[128];
    snprintf(w, sizeof w, "%s/fft.wis", dir);
    snprintf(w16, sizeof w16, "%s/pcg3only.wis", dir);
    snprintf(h5, sizeof h5, "%s/sim.h5", dir);
    ck_assert_int_eq(run("wisdom data/presets/demo.cfg --out %s --dry-run", w), 0);
    ck_assert_int_ne(access(w, F_OK), 0);
    ck_assert_int_eq(run("wisdom data/presets/demo.cfg --out %s", w), 0);
    FILE *f = fopen(w, "r");
    ck_assert_ptr_nonnull(f);
    char head[8] = {0};
    ck_assert_uint_eq(fread(head, 1, 6, f), 6);
    fclose(f);
    ck_assert_str_eq(head, "(fftw-");
    char want[65];
    ck_assert_int_eq(wt_sha256_file(w, want), 0);
    char tel[128], cmds[128], moved[128];
    snprintf(tel, sizeof tel, "%s/tel.h5", dir);
    snprintf(cmds, sizeof cmds, "%s/cmds.h5", dir);
    snprintf(moved, sizeof moved, "%s/moved.wis", dir);
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --recon cg9 --frames 3 --quiet --out %s --telemetry %s "
                         "--set 'recon.fft_wisdom=\"%s\"'", h5, tel, w), 0);
    /* the replay plans from the stored file; without it, refused naming the key; --set turns it off */
    ck_assert_int_eq(run("run --telemetry %s --recon cg9 --out %s --quiet", tel, cmds), 0);
    ck_assert_int_eq(rename(w, moved), 0);
    ck_assert_int_eq(run("run --telemetry %s --recon cg9 --out %s --quiet", tel, cmds), 1);
    ck_assert(stderr_has("recon.fft_wisdom") && stderr_has("fft.wis"));
    ck_assert_int_eq(run("run --telemetry %s --recon cg9 --out %s --quiet --set 'recon.fft_wisdom=\"\"'", tel, cmds), 0);
    ck_assert_int_eq(rename(moved, w), 0);
    wt_context *ctx = tu_context();
    wt_h5_reader *r = NULL;
    char *text = NULL;
    ck_assert_int_eq(wt_h5_open(ctx, h5, &r), WT_OK);
    ck_assert_int_eq(wt_h5_read_string(r, "config", &text), WT_OK);
    ck_assert_ptr_nonnull(strstr(text, want));
    wt_free(ctx, text);
    wt_h5_close(r);
    wt_context_free(ctx);
    /* cg9's full prior only: its layers are all 32 x 32, pcg3's 16 x 16 layer is missing */
    ck_assert_int_eq(run("wisdom data/presets/demo.cfg --out %s --set 'recon.pcg3.prior=\"paper\"'", w16), 0);
    ck_assert_int_eq(run("sim --config data/presets/demo.cfg --recon pcg3 --frames 3 --quiet --out %s "
                         "--set 'recon.fft_wisdom=\"%s\"'", h5, w16), 1);
    ck_assert(stderr_has("recon.fft_wisdom") && stderr_has("16 x 16"));
    ck_assert_int_eq(run("wisdom data/presets/demo.cfg"), 2);
    ck_assert_int_eq(run("wisdom data/presets/demo.cfg --out %s --set 'recon.prior=\"paper\"'", w), 1);
    ck_assert(stderr_has("full prior"));
    ck_assert_int_eq(run("wisdom data/presets/demo.cfg --out %s", h5), 1);
}
END_TEST

START_TEST(test_info_spots)
{
    char out[128];
    snprintf(out, sizeof out, "%s/spots/nested", dir); /* created like mkdir -p */
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz --spots %s", out), 0);
    /* the demo's 16 x 16 cells of 10 px: 4 screen px per detector px, no insets (wt_plot_spots_page) */
    unsigned w, h;
    png_size(out, "spots_LGS1.png", &w, &h);
    ck_assert_msg(w == 1431 && h == 1051, "spots_LGS1.png is %u x %u", w, h);
    ck_assert_msg(file_size(out, "spots_LGS1.png") > 20000, "spots_LGS1.png is (nearly) empty");
    png_size(out, "gain_LGS1.png", &w, &h);
    ck_assert_msg(w == 1500 && h == 720, "gain_LGS1.png is %u x %u", w, h);
    char text[8192] = {0};
    ck_assert(read_text(out, "spots.md", text, sizeof text));
    ck_assert(!strncmp(text, "# wavetomo spot images: LGS1", 28));
    ck_assert(strstr(text, "median NEA") && strstr(text, "worst truncation") && strstr(text, "spots_LGS1.png"));
    /* again into the same directory: ours, replaced; another sensor by name */
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz --spots %s --sensor lgs3", out), 0);
    ck_assert(is_png(out, "spots_LGS3.png") && is_png(out, "gain_LGS3.png"));

    /* a geometric system: a clear refusal, exit 1, no directory made */
    snprintf(out, sizeof out, "%s/geo", dir);
    ck_assert_int_eq(run("info data/presets/demo.cfg --no-nnz --spots %s", out), 1);
    ck_assert(stderr_has("geometric"));
    ck_assert(stderr_has("lgs.wfs.model"));
    ck_assert_int_ne(access(out, F_OK), 0);
    /* an unknown sensor names the ones there are; --sensor alone is a usage error */
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz --spots %s --sensor LGS9", out), 1);
    ck_assert(stderr_has("LGS1, LGS2"));
    ck_assert_int_ne(access(out, F_OK), 0);
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --sensor LGS1"), 2);
    ck_assert_int_eq(run("info --help"), 0);
    /* --time T: the sequence's spots then (spots.md says so); refused without a sequence, outside it, not a number,
     * or without --spots */
    const char *seq = "--set 'lgs.sodium_sequence=\"../sodium/drift-1km-10min.txt\"'";
    snprintf(out, sizeof out, "%s/at600", dir);
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz %s --spots %s --time 600", seq, out), 0);
    ck_assert(read_text(out, "spots.md", text, sizeof text));
    ck_assert(strstr(text, "At night time 600.0 s") && strstr(text, "false signal"));
    snprintf(out, sizeof out, "%s/attime", dir);
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz --spots %s --time 50", out), 1);
    ck_assert(stderr_has("lgs.sodium_sequence"));
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz %s --spots %s --time 5000", seq, out), 1);
    ck_assert(stderr_has("--time 5000") && stderr_has("drift-1km-10min.txt"));
    ck_assert_int_ne(access(out, F_OK), 0);
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --no-nnz %s --spots %s --time 6x", seq, out), 2);
    ck_assert_int_eq(run("info data/presets/demo-diffractive.cfg --time 60"), 2);

    /* compare on the diffractive demo writes and links the pictures */
    snprintf(out, sizeof out, "%s/cmp", dir);
    ck_assert_int_eq(run("compare --config data/presets/demo-diffractive.cfg --recon pcg3 --frames 8 --out %s --quiet",
                         out),
                     0);
    ck_assert(is_png(out, "spots_LGS1.png") && is_png(out, "gain_LGS1.png"));
    ck_assert(file_size(out, "spots.md") > 500);
    ck_assert(read_text(out, "report.md", text, sizeof text));
    ck_assert(strstr(text, "(spots_LGS1.png)") && strstr(text, "(gain_LGS1.png)"));
    /* without a sweep the table has no sweep column (it would hold nothing), and one method has no difference map */
    ck_assert_msg(strstr(text, "| method | LE Strehl on-axis") && strstr(text, "| pcg3 | 0.") && !strstr(text, "| – |"),
                  "%s", text);
    ck_assert_int_lt(file_size(out, "diff_pcg3_pcg3_0.png"), 0);
    ck_assert(!strstr(text, "## Differences between methods"));
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("cli");
    TCase *tc = tcase_create("commands");
    tcase_add_checked_fixture(tc, setup, teardown);
    tcase_set_timeout(tc, 300);
    tcase_add_test(tc, test_compare_writes_the_report);
    tcase_add_test(tc, test_compare_learned_report);
    tcase_add_test(tc, test_build_run_chain_and_refusals);
    tcase_add_test(tc, test_run_rejects_bad_frames);
    tcase_add_test(tc, test_did_you_mean);
    tcase_add_test(tc, test_info_spots);
    tcase_add_test(tc, test_wisdom_command);
    tcase_add_test(tc, test_sim_interrupt);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
