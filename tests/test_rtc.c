/* tests/test_rtc.c: the public per-frame API (include/wavetomo/rtc.h): its commands are `wavetomo run`'s
 * bit for bit (pcg3, cg9, the MVM; float32 and float64 entries), its POLC is the closed loop's
 * (sim/loop.c) bit for bit, a frame allocates nothing, reset and RAW frames keep the state they
 * promise, instances run concurrently, the orderings are the output files' layout, Â is the frame's POLC
 * term, and bad input is refused with a message naming it. The demo preset throughout; `wavetomo sim/build/run` made the files
 * ($BIN/wavetomo, which make test builds first). */
#include <pthread.h>
#include <stdarg.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/config/config.h"
#include "core/io/h5.h"
#include "runtime/rtc_internal.h"
#include "sim/loop.h"
#include "core/solve/mvm.h"
#include "testutil.h"
#include "wavetomo/wavetomo.h"

#define DEMO "data/presets/demo.cfg"
#define FRAMES 8

static char dir[64], wt[512];

static int sh(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int sh(const char *fmt, ...)
{
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    int n = snprintf(cmd, sizeof cmd, "%s ", wt);
    vsnprintf(cmd + n, sizeof cmd - (size_t)n, fmt, ap);
    va_end(ap);
    size_t l = strlen(cmd);
    snprintf(cmd + l, sizeof cmd - l, " --threads 1 --quiet > /dev/null 2>> %s/stderr.txt", dir);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Once per test case (in the parent process): the telemetry of a pcg3 loop and of an MVM loop, the
 * matrix, and `wavetomo run`'s reconstructions of them (pcg3 and cg9 on the pcg3 telemetry). */
static void files_setup(void)
{
    tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt-rtc-");
    const char *c = "--config " DEMO " --frames 8 --seed 3";
    int ok = sh("sim %s --recon pcg3 --out %s/r.h5 --telemetry %s/tel.h5", c, dir, dir) == 0 &&
             sh("build --config " DEMO " --recon pcg3 --out %s/M.h5", dir) == 0 &&
             sh("sim %s --recon mvm --matrix %s/M.h5 --out %s/rm.h5 --telemetry %s/tel-mvm.h5", c, dir, dir, dir) == 0 &&
             sh("run --recon pcg3 --telemetry %s/tel.h5 --out %s/run-pcg3.h5", dir, dir) == 0 &&
             sh("run --recon cg9 --telemetry %s/tel.h5 --out %s/run-cg9.h5", dir, dir) == 0 &&
             sh("run --matrix %s/M.h5 --telemetry %s/tel-mvm.h5 --out %s/run-mvm.h5", dir, dir, dir) == 0;
    if (!ok) {
        char cmd[128];
        snprintf(cmd, sizeof cmd, "cat %s/stderr.txt >&2", dir);
        if (system(cmd) != 0) fprintf(stderr, "(no stderr)\n");
    }
    ck_assert_msg(ok, "wavetomo sim/build/run failed (stderr above)");
}

static void files_teardown(void) { tu_cli_teardown(dir); }

static void path(char *p, size_t n, const char *name) { snprintf(p, n, "%s/%s", dir, name); }

/* The whole float32 series `name` of file `file` (frames x n values), malloc'ed; *frames its rows. */
static float *read_series(const char *file, const char *name, int64_t n, int64_t *frames)
{
    wt_context *ctx = tu_context();
    wt_h5_reader *r;
    char p[256];
    path(p, sizeof p, file);
    ck_assert_msg(wt_h5_open(ctx, p, &r) == WT_OK, "%s", wt_error_message(ctx));
    int64_t e[2] = {-1, n}, d[2];
    ck_assert_msg(wt_h5_check_shape(r, name, 2, e, d) == WT_OK, "%s", wt_error_message(ctx));
    float *x = malloc((size_t)(d[0] * n) * sizeof *x);
    ck_assert_int_eq(wt_h5_read_rows(r, name, WT_H5_F32, 0, d[0], x), WT_OK);
    wt_h5_close(r);
    wt_context_free(ctx);
    *frames = d[0];
    return x;
}

static char *read_text(const char *file, const char *name)
{
    wt_context *ctx = tu_context();
    wt_h5_reader *r;
    char p[256], *text, *copy;
    path(p, sizeof p, file);
    ck_assert_int_eq(wt_h5_open(ctx, p, &r), WT_OK);
    ck_assert_int_eq(wt_h5_read_string(r, name, &text), WT_OK);
    copy = strdup(text);
    wt_free(ctx, text);
    wt_h5_close(r);
    wt_context_free(ctx);
    return copy;
}

/* An instance of case k: 0 pcg3, 1 cg9 on the pcg3 loop's telemetry's configuration, 2 the MVM (the
 * configuration stored in the matrix). */
static wt_rtc *open_case(wt_context *ctx, int k)
{
    wt_rtc *rtc = NULL;
    int st;
    if (k < 2) {
        char *text = read_text("tel.h5", "config");
        st = wt_rtc_open_text(ctx, k ? "cg9" : "pcg3", text, 0, NULL, &rtc);
        free(text);
    } else {
        char m[256];
        path(m, sizeof m, "M.h5");
        st = wt_rtc_open_mvm(ctx, m, NULL, 0, NULL, &rtc);
    }
    ck_assert_msg(st == WT_OK, "open: %s", wt_error_message(ctx));
    return rtc;
}

START_TEST(test_version)
{
    char v[32];
    snprintf(v, sizeof v, "%d.%d.%d", WT_VERSION_MAJOR, WT_VERSION_MINOR, WT_VERSION_PATCH);
    ck_assert_str_eq(v, WT_VERSION_STRING);
    ck_assert_str_eq(wt_version(), WT_VERSION_STRING);
    ck_assert_int_eq(wt_version_number(), WT_VERSION_NUMBER);
    ck_assert_str_eq(WT_VERSION, WT_VERSION_STRING); /* the internal name the output files record */
}
END_TEST

/* `wavetomo run` replays telemetry in RAW mode: the API's float32 and float64 entries give its stored
 * float32 reconstructions bit for bit (pcg3 and cg9 on s_ol; the MVM on s and the applied commands, its
 * POLC form R s + (R Â) a). The float64 entry is exact too: a float converts to double and back
 * unchanged, and the reconstructors compute in double (the MVM in float) either way. */
START_TEST(test_equals_run)
{
    const int k = _i;
    const char *runs[] = {"run-pcg3.h5", "run-cg9.h5", "run-mvm.h5"};
    wt_context *ctx = tu_context();
    wt_rtc *rtc = open_case(ctx, k), *rtc64 = open_case(ctx, k);
    const int64_t ns = wt_rtc_nslopes(rtc), na = wt_rtc_nactuators(rtc);
    int64_t F, F2, F3 = 0;
    float *s = read_series(k < 2 ? "tel.h5" : "tel-mvm.h5", k < 2 ? "slopes_ol" : "slopes", ns, &F);
    float *ref = read_series(runs[k], "reconstruction", na, &F2);
    float *a = k == 2 ? read_series("tel-mvm.h5", "commands", na, &F3) : NULL;
    ck_assert_int_eq(F, FRAMES);
    ck_assert_int_eq(F2, FRAMES);
    const unsigned flags = WT_RTC_RAW | (k < 2 ? WT_RTC_SLOPES_OL : 0);
    float *c = malloc((size_t)na * sizeof *c);
    double *sd = malloc((size_t)ns * sizeof *sd), *ad = malloc((size_t)na * sizeof *ad),
           *cd = malloc((size_t)na * sizeof *cd);
    for (int64_t t = 0; t < F; t++) {
        const float *at = a ? a + t * na : NULL;
        ck_assert_msg(wt_rtc_frame_f32(rtc, s + t * ns, ns, at, flags, c, na) >= 0, "%s", wt_error_message(ctx));
        ck_assert_msg(!memcmp(c, ref + t * na, (size_t)na * sizeof *c), "%s frame %lld (f32) differs from wavetomo run",
                      wt_rtc_recon(rtc), (long long)t);
        for (int64_t i = 0; i < ns; i++) sd[i] = s[t * ns + i];
        for (int64_t i = 0; at && i < na; i++) ad[i] = at[i];
        ck_assert_msg(wt_rtc_frame(rtc64, sd, ns, at ? ad : NULL, flags, cd, na) >= 0, "%s", wt_error_message(ctx));
        for (int64_t i = 0; i < na; i++)
            ck_assert_msg((float)cd[i] == ref[t * na + i], "%s frame %lld (f64) command %lld: %.9g vs %.9g",
                          wt_rtc_recon(rtc), (long long)t, (long long)i, cd[i], (double)ref[t * na + i]);
        ck_assert(wt_rtc_frame_time(rtc) > 0.0);
    }
    ck_assert_int_eq(wt_rtc_frames(rtc), F);
    free(s), free(ref), free(a), free(c), free(sd), free(ad), free(cd);
    wt_rtc_close(rtc);
    wt_rtc_close(rtc64);
    wt_context_free(ctx);
}
END_TEST

/* With POLC inside, the API fed a closed loop's measured slopes returns the commands that loop applies d
 * frames later, bit for bit: the same reconstructor state, s_ol = s + Â a_t and integrator, in the same
 * operations (pcg3, cg9: from the API's own command queue). For the MVM, fed the loop's s_ol and applied
 * commands (WT_RTC_SLOPES_OL: r = R s_ol, the loop's form), also bit for bit; from s and its own queue
 * (r = R s + (R Â) a_t, rounded differently in float32) within 1e-4 of the commands' norm: a float32
 * GEMV of ~2000 terms rounds at ~1e-6 relative, accumulated over 8 frames of an integrator of gain < 1;
 * a missing or mis-signed POLC term is an O(1) difference. Cases 4–7 again with the scale-dependent gain
 * (loop.gain_levels, one law for both: runtime/control.h), 8–11 with it and a delay of 1 frame: every
 * reconstructor under both gain laws, and delays 1 and 2; 12–13 pcg3 and cg9 predicting with the integrator on their
 * layers (recon.predict_integrator = "layers"). */
START_TEST(test_polc_equals_loop)
{
    const int k = _i % 4; /* 0 pcg3, 1 cg9, 2 MVM via s_ol, 3 MVM via s */
    wt_context *ctx = tu_context();
    const char *set0[] = {"loop.frames=8", "sim.seed=5", "evaluation.settle_frames=2",
                          "loop.gain_levels=[0.6, 0.5, 0.4, 0.3]", "loop.delay_frames=1"};
    /* cases 12, 13: pcg3 and cg9 with prediction and the integrator on their layers (the control applies what the
     * reconstructor returns; one module for both) */
    const char *set1[] = {"loop.frames=8", "sim.seed=5", "evaluation.settle_frames=2", "recon.predict=true",
                          "recon.predict_integrator=\"layers\""};
    const char **set = _i >= 12 ? set1 : set0;
    const int nset = _i >= 12 ? 5 : 3 + _i / 4; /* 3: scalar gain, delay 2; 4: gain levels, delay 2; 5: gain levels, delay 1 */
    wt_config *cfg;
    wt_system *sys;
    wt_loop *lp;
    wt_rtc *rtc;
    ck_assert_int_eq(wt_config_read(ctx, DEMO, nset, set, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    char m[256];
    path(m, sizeof m, "M.h5");
    struct wt_mvm *mvm = NULL;
    if (k >= 2) {
        ck_assert_msg(wt_rtc_open_mvm(ctx, m, DEMO, nset, set, &rtc) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_eq(wt_mvm_read(ctx, m, cfg, sys->nact, sys->nslopes, &mvm, NULL), WT_OK);
    } else {
        ck_assert_msg(wt_rtc_open(ctx, k ? "cg9" : "pcg3", DEMO, nset, set, &rtc) == WT_OK, "%s", wt_error_message(ctx));
    }
    wt_loop_options o = {.recon = k == 0 ? WT_RECON_PCG3 : k == 1 ? WT_RECON_CG9 : WT_RECON_MVM, .mvm = mvm,
                         .iterations = -1, .seed = cfg->seed, .noise = cfg->noise};
    ck_assert_int_eq(wt_loop_alloc(ctx, sys, &o, &lp), WT_OK);
    const int d = wt_rtc_delay(rtc);
    const int64_t na = sys->nact, ns = sys->nslopes;
    ck_assert_int_eq(d, cfg->delay);
    ck_assert_int_eq(wt_rtc_nactuators(rtc), na);
    double *out = calloc((size_t)(FRAMES * na), sizeof *out), worst = 0.0;
    for (int t = 0; t < FRAMES; t++) {
        ck_assert_int_eq(wt_loop_step(lp), WT_OK);
        if (t >= d) { /* a_t, applied during frame t, was returned at frame t - d */
            const double *a = wt_loop_applied(lp), *mine = out + (t - d) * na;
            if (k < 3) {
                ck_assert_msg(!memcmp(a, mine, (size_t)na * sizeof *a), "case %d: frame %d's commands differ", k, t);
            } else {
                double dn = 0.0, an = 0.0;
                for (int64_t i = 0; i < na; i++) dn += (a[i] - mine[i]) * (a[i] - mine[i]), an += a[i] * a[i];
                worst = fmax(worst, sqrt(dn / an));
            }
        }
        int st = k == 2 ? wt_rtc_frame(rtc, wt_loop_slopes_ol(lp), ns, wt_loop_applied(lp), WT_RTC_SLOPES_OL,
                                       out + t * na, na)
                        : wt_rtc_frame(rtc, wt_loop_slopes(lp), ns, NULL, 0, out + t * na, na);
        ck_assert_msg(st >= 0, "%s", wt_error_message(ctx));
    }
    ck_assert_msg(worst <= 1e-4, "MVM from s: relative difference %.3g", worst);
    free(out);
    wt_loop_free(lp);
    wt_rtc_close(rtc);
    wt_mvm_free(mvm);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* The frame call allocates nothing through the context (every mode, both entries, reset), nor does Â
 * (wt_rtc_interaction, _t), and close frees everything open allocated. */
START_TEST(test_no_allocation_per_frame)
{
    const int k = _i;
    tu_alloc al = TU_ALLOC_INIT;
    wt_context *ctx = tu_context();
    tu_alloc_install(ctx, &al);
    wt_rtc *rtc = open_case(ctx, k == 0 ? 0 : 2);
    const int64_t ns = wt_rtc_nslopes(rtc), na = wt_rtc_nactuators(rtc);
    double *s = malloc((size_t)ns * sizeof *s), *a = malloc((size_t)na * sizeof *a);
    float *sf = malloc((size_t)ns * sizeof *sf), *af = malloc((size_t)na * sizeof *af);
    tu_randn(s, ns, 7);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-7, sf[i] = (float)s[i];
    const long before = al.count;
    for (int t = 0; t < 3; t++) {
        ck_assert_int_ge(wt_rtc_frame(rtc, s, ns, NULL, 0, a, na), 0);
        ck_assert_int_ge(wt_rtc_frame(rtc, s, ns, a, WT_RTC_RAW, a, na), 0);
        ck_assert_int_ge(wt_rtc_frame_f32(rtc, sf, ns, NULL, 0, af, na), 0);
        ck_assert_int_ge(wt_rtc_frame_f32(rtc, sf, ns, af, WT_RTC_RAW, af, na), 0);
        ck_assert_int_ge(wt_rtc_frame_f32(rtc, sf, ns, NULL, WT_RTC_RAW | WT_RTC_SLOPES_OL, af, na), 0);
        ck_assert_int_eq(wt_rtc_interaction_t(rtc, s, ns, a, na), WT_OK);
        ck_assert_int_eq(wt_rtc_interaction(rtc, a, na, s, ns), WT_OK);
        wt_rtc_reset(rtc);
    }
    ck_assert_msg(al.count == before, "%s: %ld allocations in 15 frames and 6 applications of Â", wt_rtc_recon(rtc),
                  al.count - before);
    wt_rtc_close(rtc);
    ck_assert_int_eq(al.live, 0);
    free(s), free(a), free(sf), free(af);
    wt_context_free(ctx);
}
END_TEST

/* reset forgets everything: the frames after it repeat the first ones bit for bit (warm start, command
 * queue). A RAW frame leaves the integrator alone (the MVM has no other state): POLC, RAW, POLC gives the
 * second POLC frame of POLC, POLC. */
START_TEST(test_reset_and_raw)
{
    wt_context *ctx = tu_context();
    for (int k = 0; k < 3; k += 2) {
        wt_rtc *rtc = open_case(ctx, k), *b = open_case(ctx, k);
        const int64_t ns = wt_rtc_nslopes(rtc), na = wt_rtc_nactuators(rtc);
        double *s = malloc((size_t)(4 * ns) * sizeof *s), *c1 = malloc((size_t)(4 * na) * sizeof *c1),
               *c2 = malloc((size_t)na * sizeof *c2);
        tu_randn(s, 4 * ns, 11);
        for (int64_t i = 0; i < 4 * ns; i++) s[i] *= 1e-7;
        for (int t = 0; t < 4; t++) ck_assert_int_ge(wt_rtc_frame(rtc, s + t * ns, ns, NULL, 0, c1 + t * na, na), 0);
        wt_rtc_reset(rtc);
        ck_assert_int_eq(wt_rtc_frames(rtc), 0);
        for (int t = 0; t < 4; t++) {
            ck_assert_int_ge(wt_rtc_frame(rtc, s + t * ns, ns, NULL, 0, c2, na), 0);
            ck_assert_msg(!memcmp(c2, c1 + t * na, (size_t)na * sizeof *c2), "%s: frame %d after reset differs",
                          wt_rtc_recon(rtc), t);
        }
        if (k == 2) {
            ck_assert_int_ge(wt_rtc_frame(b, s, ns, NULL, 0, c2, na), 0);
            ck_assert_int_ge(wt_rtc_frame(b, s + 3 * ns, ns, NULL, WT_RTC_RAW, c2, na), 0);
            ck_assert_int_ge(wt_rtc_frame(b, s + ns, ns, NULL, 0, c2, na), 0);
            ck_assert(!memcmp(c2, c1 + na, (size_t)na * sizeof *c2));
        }
        free(s), free(c1), free(c2);
        wt_rtc_close(rtc);
        wt_rtc_close(b);
    }
    wt_context_free(ctx);
}
END_TEST

/* Two instances (one context each) running frames at the same time from two threads give what they give
 * one after the other. */
typedef struct job {
    wt_context *ctx;
    wt_rtc *rtc;
    const double *s;
    double *out;
    int st;
} job;

static void *run_job(void *arg)
{
    job *j = arg;
    const int64_t ns = wt_rtc_nslopes(j->rtc), na = wt_rtc_nactuators(j->rtc);
    for (int t = 0; t < 4 && j->st >= 0; t++) j->st = wt_rtc_frame(j->rtc, j->s + t * ns, ns, NULL, 0, j->out + t * na, na);
    return NULL;
}

START_TEST(test_instances_in_threads)
{
    job j[4];
    for (int i = 0; i < 4; i++) {
        j[i].ctx = tu_context();
        j[i].rtc = open_case(j[i].ctx, i % 2 ? 2 : 0); /* pcg3 and the MVM, twice */
        const int64_t ns = wt_rtc_nslopes(j[i].rtc), na = wt_rtc_nactuators(j[i].rtc);
        double *s = malloc((size_t)(4 * ns) * sizeof *s);
        tu_randn(s, 4 * ns, 20 + (unsigned long)(i % 2));
        for (int64_t q = 0; q < 4 * ns; q++) s[q] *= 1e-7;
        j[i].s = s;
        j[i].out = calloc((size_t)(4 * na), sizeof *j[i].out);
        j[i].st = WT_OK;
    }
    run_job(&j[0]); /* the reference, alone */
    run_job(&j[1]);
    pthread_t th[2];
    for (int i = 0; i < 2; i++) ck_assert_int_eq(pthread_create(&th[i], NULL, run_job, &j[2 + i]), 0);
    for (int i = 0; i < 2; i++) ck_assert_int_eq(pthread_join(th[i], NULL), 0);
    for (int i = 0; i < 2; i++) {
        ck_assert_msg(j[2 + i].st >= 0, "%s", wt_error_message(j[2 + i].ctx));
        ck_assert(!memcmp(j[i].out, j[2 + i].out, (size_t)(4 * wt_rtc_nactuators(j[i].rtc)) * sizeof(double)));
    }
    for (int i = 0; i < 4; i++) {
        free((void *)j[i].s), free(j[i].out);
        wt_rtc_close(j[i].rtc);
        wt_context_free(j[i].ctx);
    }
}
END_TEST

/* Several loops on one plan (wt_rtc_share): an original A and its share B, fed different slopes in turns, give
 * exactly the commands of two instances opened independently (pcg3, cg9, the MVM; delay 2 with loop.gain_levels),
 * Â included; the original closed half-way leaves the share running on the plan. The share of the MVM allocates
 * (through its context) less than one R: R and R Â are not copied; every block of both contexts is freed. */
static void *bytes_malloc(void *user, size_t n)
{
    size_t *p = malloc(n + 16);
    if (!p) return NULL;
    *(size_t *)user += n;
    *p = n;
    return (char *)p + 16;
}

static void bytes_free(void *user, void *q)
{
    if (!q) return;
    size_t *p = (size_t *)((char *)q - 16);
    *(size_t *)user -= *p; /* user: the bytes live */
    free(p);
}

START_TEST(test_share_equals_open)
{
    const int k = _i; /* 0 pcg3, 1 cg9, 2 the MVM */
    const char *set[] = {"loop.delay_frames=2", "loop.gain_levels=[0.6, 0.5, 0.4, 0.3]"};
    size_t live[2] = {0, 0}, peak_share;
    wt_context *ctx[3] = {tu_context(), tu_context(), tu_context()};
    for (int i = 0; i < 2; i++) wt_context_set_allocator(ctx[i], bytes_malloc, bytes_free, &live[i]);
    wt_rtc *r[4]; /* A, its share B, and the independent C, D */
    char m[256];
    path(m, sizeof m, "M.h5");
    for (int i = 0; i < 4; i++) {
        if (i == 1) continue;
        wt_context *c = i == 0 ? ctx[0] : ctx[2];
        int st = k == 2 ? wt_rtc_open_mvm(c, m, DEMO, 2, set, &r[i]) : wt_rtc_open(c, k ? "cg9" : "pcg3", DEMO, 2, set, &r[i]);
        ck_assert_msg(st == WT_OK, "%s", wt_error_message(c));
    }
    ck_assert_msg(wt_rtc_share(ctx[1], r[0], &r[1]) == WT_OK, "%s", wt_error_message(ctx[1]));
    peak_share = live[1];
    const int64_t ns = wt_rtc_nslopes(r[0]), na = wt_rtc_nactuators(r[0]);
    ck_assert_int_eq(wt_rtc_nslopes(r[1]), ns);
    ck_assert_str_eq(wt_rtc_recon(r[1]), wt_rtc_recon(r[0]));
    ck_assert_str_eq(wt_rtc_config(r[1]), wt_rtc_config(r[0]));
    ck_assert_int_eq(wt_rtc_delay(r[1]), 2);
    if (k == 2) /* R alone is 4 na ns bytes */
        ck_assert_msg(peak_share < (size_t)(4 * na * ns) && live[0] > (size_t)(4 * na * ns),
                      "the share allocated %zu bytes, the original %zu, R is %lld", peak_share, live[0],
                      (long long)(4 * na * ns));
    double *s = malloc((size_t)(2 * FRAMES * ns) * sizeof *s), *c = malloc((size_t)(4 * na) * sizeof *c),
           *ia = malloc((size_t)(2 * ns) * sizeof *ia);
    tu_randn(s, 2 * FRAMES * ns, 31);
    for (int64_t i = 0; i < 2 * FRAMES * ns; i++) s[i] *= 1e-7;
    for (int t = 0; t < FRAMES; t++) {
        if (t == FRAMES / 2) { /* the original goes: the share keeps the plan */
            wt_rtc_close(r[0]);
            r[0] = NULL;
        }
        for (int i = 0; i < 4; i++) { /* A and C take the first series, B and D the second */
            if (!r[i]) continue;
            const double *st = s + ((size_t)(i % 2) * FRAMES + (size_t)t) * (size_t)ns;
            ck_assert_msg(wt_rtc_frame(r[i], st, ns, NULL, 0, c + i * na, na) >= 0, "%s", wt_error_message(ctx[i < 2 ? i : 2]));
        }
        for (int i = 0; i < 2; i++)
            ck_assert_msg(!r[i] || !memcmp(c + i * na, c + (i + 2) * na, (size_t)na * sizeof *c),
                          "%s: frame %d of the %s differs from an independent instance's", wt_rtc_recon(r[1]), t,
                          i ? "share" : "original");
    }
    ck_assert_int_eq(wt_rtc_frames(r[1]), FRAMES);
    ck_assert_int_eq(wt_rtc_interaction(r[1], c + na, na, ia, ns), WT_OK); /* Â with the share's workspace */
    ck_assert_int_eq(wt_rtc_interaction(r[3], c + na, na, ia + ns, ns), WT_OK);
    ck_assert(!memcmp(ia, ia + ns, (size_t)ns * sizeof *ia));
    for (int i = 1; i < 4; i++) wt_rtc_close(r[i]);
    ck_assert_msg(live[0] == 0 && live[1] == 0, "%zu and %zu bytes left", live[0], live[1]);
    free(s), free(c), free(ia);
    for (int i = 0; i < 3; i++) wt_context_free(ctx[i]);
}
END_TEST

/* Shares of one plan (one context each) running frames at once from two threads give what two shares give one
 * after the other (pcg3: Â's operator shared; the MVM: R and R Â). */
START_TEST(test_shares_in_threads)
{
    for (int k = 0; k < 3; k += 2) {
        wt_context *c0 = tu_context();
        wt_rtc *plan = open_case(c0, k);
        job j[4];
        for (int i = 0; i < 4; i++) {
            j[i].ctx = tu_context();
            ck_assert_int_eq(wt_rtc_share(j[i].ctx, plan, &j[i].rtc), WT_OK);
            const int64_t ns = wt_rtc_nslopes(j[i].rtc), na = wt_rtc_nactuators(j[i].rtc);
            double *s = malloc((size_t)(4 * ns) * sizeof *s);
            tu_randn(s, 4 * ns, 40 + (unsigned long)(i % 2));
            for (int64_t q = 0; q < 4 * ns; q++) s[q] *= 1e-7;
            j[i].s = s;
            j[i].out = calloc((size_t)(4 * na), sizeof *j[i].out);
            j[i].st = WT_OK;
        }
        wt_rtc_close(plan); /* the shares hold the plan */
        run_job(&j[0]);
        run_job(&j[1]);
        pthread_t th[2];
        for (int i = 0; i < 2; i++) ck_assert_int_eq(pthread_create(&th[i], NULL, run_job, &j[2 + i]), 0);
        for (int i = 0; i < 2; i++) ck_assert_int_eq(pthread_join(th[i], NULL), 0);
        for (int i = 0; i < 2; i++) {
            ck_assert_msg(j[2 + i].st >= 0, "%s", wt_error_message(j[2 + i].ctx));
            ck_assert_msg(!memcmp(j[i].out, j[2 + i].out, (size_t)(4 * wt_rtc_nactuators(j[i].rtc)) * sizeof(double)),
                          "%s: share %d in a thread differs", wt_rtc_recon(j[i].rtc), i);
        }
        for (int i = 0; i < 4; i++) {
            free((void *)j[i].s), free(j[i].out);
            wt_rtc_close(j[i].rtc);
            wt_context_free(j[i].ctx);
        }
        wt_context_free(c0);
    }
}
END_TEST

/* The orderings the API reports are the "layout" group of wavetomo's output files: sensors' slope blocks
 * contiguous in order, subaperture centres, actuator positions and (DM, ix, iy). */
START_TEST(test_orderings)
{
    wt_context *ctx = tu_context(), *rc = tu_context();
    wt_rtc *rtc = open_case(ctx, 0);
    const int64_t ns = wt_rtc_nslopes(rtc), na = wt_rtc_nactuators(rtc);
    wt_h5_reader *r;
    char p[256];
    path(p, sizeof p, "run-pcg3.h5");
    ck_assert_int_eq(wt_h5_open(rc, p, &r), WT_OK);
    int64_t next = 0;
    int nlgs = 0;
    for (int m = 0; m < wt_rtc_nsensors(rtc); m++) {
        wt_rtc_sensor si;
        ck_assert_int_eq(wt_rtc_sensor_info(rtc, m, &si), WT_OK);
        ck_assert_int_eq(si.offset, next);
        ck_assert(si.kind == WT_RTC_LGS ? nlgs++ == m : si.altitude == 0.0); /* LGS first */
        next += 2 * si.nsub;
        double *xy = malloc((size_t)(2 * si.nsub) * sizeof *xy), *ref = malloc((size_t)(2 * si.nsub) * sizeof *ref);
        ck_assert_int_eq(wt_rtc_subapertures(rtc, m, xy), WT_OK);
        char name[64];
        snprintf(name, sizeof name, "layout/%s/subaperture_centre", si.name);
        int64_t e[2] = {si.nsub, 2};
        ck_assert_msg(wt_h5_read(r, name, WT_H5_F64, 2, e, NULL, ref, 2 * si.nsub) == WT_OK, "%s", wt_error_message(rc));
        ck_assert(!memcmp(xy, ref, (size_t)(2 * si.nsub) * sizeof *xy));
        free(xy), free(ref);
    }
    ck_assert_int_eq(next, ns);
    ck_assert(nlgs > 0);
    next = 0;
    for (int k = 0; k < wt_rtc_ndms(rtc); k++) {
        wt_rtc_dm di;
        ck_assert_int_eq(wt_rtc_dm_info(rtc, k, &di), WT_OK);
        ck_assert_int_eq(di.offset, next);
        ck_assert(di.pitch > 0.0 && di.nactive > 0 && di.nactive <= di.nx * di.ny);
        next += di.nactive;
    }
    ck_assert_int_eq(next, na);
    double *xy = malloc((size_t)(2 * na) * sizeof *xy), *rxy = malloc((size_t)(2 * na) * sizeof *rxy);
    int32_t *ix = malloc((size_t)(3 * na) * sizeof *ix), *rix = malloc((size_t)(3 * na) * sizeof *rix);
    ck_assert_int_eq(wt_rtc_actuators(rtc, xy, ix), WT_OK);
    int64_t e2[2] = {na, 2}, e3[2] = {na, 3};
    ck_assert_int_eq(wt_h5_read(r, "layout/actuator_position", WT_H5_F64, 2, e2, NULL, rxy, 2 * na), WT_OK);
    ck_assert_int_eq(wt_h5_read(r, "layout/actuator_index", WT_H5_I32, 2, e3, NULL, rix, 3 * na), WT_OK);
    ck_assert(!memcmp(xy, rxy, (size_t)(2 * na) * sizeof *xy));
    ck_assert(!memcmp(ix, rix, (size_t)(3 * na) * sizeof *ix));
    for (int64_t i = 0; i < na; i++) { /* a DM's actuators are its grid points */
        wt_rtc_dm di;
        wt_rtc_dm_info(rtc, ix[3 * i], &di);
        ck_assert(xy[2 * i] == di.x0 + ix[3 * i + 1] * di.pitch && xy[2 * i + 1] == di.y0 + ix[3 * i + 2] * di.pitch);
    }
    ck_assert_str_eq(wt_rtc_recon(rtc), "pcg3");
    ck_assert(wt_rtc_gain(rtc) > 0.0 && wt_rtc_gain(rtc) <= 1.0 && wt_rtc_rate(rtc) > 0.0);
    free(xy), free(rxy), free(ix), free(rix);
    wt_h5_close(r);
    wt_rtc_close(rtc);
    wt_context_free(rc);
    wt_context_free(ctx);
}
END_TEST

static int has(wt_context *ctx, const char *text) { return strstr(wt_error_message(ctx), text) != NULL; }

/* Bad input at the frame: NaN or Inf naming the frame, the index and what it is, before any state
 * changes; sizes naming both; NULL buffers; unknown flags. */
START_TEST(test_bad_frames)
{
    wt_context *ctx = tu_context();
    wt_rtc *rtc = open_case(ctx, 0), *ref = open_case(ctx, 0);
    const int64_t ns = wt_rtc_nslopes(rtc), na = wt_rtc_nactuators(rtc);
    double *s = calloc((size_t)ns, sizeof *s), *a = calloc((size_t)na, sizeof *a), *b = calloc((size_t)na, sizeof *b);
    tu_randn(s, ns, 3);
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-7;
    for (int t = 0; t < 2; t++) {
        ck_assert_int_ge(wt_rtc_frame(rtc, s, ns, NULL, 0, a, na), 0);
        ck_assert_int_ge(wt_rtc_frame(ref, s, ns, NULL, 0, b, na), 0);
    }
    const double keep = s[17];
    s[17] = NAN;
    ck_assert_int_eq(wt_rtc_frame(rtc, s, ns, NULL, 0, a, na), WT_ERR_NUMERIC);
    ck_assert_msg(has(ctx, "frame 2: slope 17 (LGS1 s_x of valid subaperture 17) is NaN"), "%s", wt_error_message(ctx));
    float *sf = calloc((size_t)ns, sizeof *sf), *af = calloc((size_t)na, sizeof *af);
    sf[ns - 1] = -INFINITY;
    ck_assert_int_eq(wt_rtc_frame_f32(rtc, sf, ns, NULL, WT_RTC_RAW, af, na), WT_ERR_NUMERIC);
    ck_assert_msg(has(ctx, "frame 2: slope") && has(ctx, "s_y of valid subaperture") && has(ctx, "is Inf"), "%s",
                  wt_error_message(ctx));
    s[17] = keep;
    double *bad = calloc((size_t)na, sizeof *bad);
    bad[na - 1] = INFINITY;
    ck_assert_int_eq(wt_rtc_frame(rtc, s, ns, bad, 0, a, na), WT_ERR_NUMERIC);
    ck_assert_msg(has(ctx, "applied command") && has(ctx, "DM 3 active actuator") && has(ctx, "Inf"), "%s",
                  wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_frame(rtc, s, ns - 1, NULL, 0, a, na), WT_ERR_INVALID);
    char want[128];
    snprintf(want, sizeof want, "%lld slopes and %lld commands given", (long long)(ns - 1), (long long)na);
    ck_assert_msg(has(ctx, want), "%s", wt_error_message(ctx));
    snprintf(want, sizeof want, "has %lld slopes and %lld commands", (long long)ns, (long long)na);
    ck_assert_msg(has(ctx, want), "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_frame(rtc, s, ns, NULL, 0, a, na + 1), WT_ERR_INVALID);
    ck_assert_int_eq(wt_rtc_frame(rtc, NULL, ns, NULL, 0, a, na), WT_ERR_INVALID);
    ck_assert(has(ctx, "slopes buffer is NULL"));
    ck_assert_int_eq(wt_rtc_frame(rtc, s, ns, NULL, 0, NULL, na), WT_ERR_INVALID);
    ck_assert_int_eq(wt_rtc_frame(rtc, s, ns, NULL, 8, a, na), WT_ERR_INVALID);
    ck_assert(has(ctx, "unknown flags 0x8"));
    ck_assert_int_eq(wt_rtc_frame(NULL, s, ns, NULL, 0, a, na), WT_ERR_INVALID);
    /* nothing changed: the next good frame is the reference's */
    ck_assert_int_eq(wt_rtc_frames(rtc), 2);
    ck_assert_int_ge(wt_rtc_frame(rtc, s, ns, NULL, 0, a, na), 0);
    ck_assert_int_ge(wt_rtc_frame(ref, s, ns, NULL, 0, b, na), 0);
    ck_assert(!memcmp(a, b, (size_t)na * sizeof *a));
    wt_rtc_sensor si;
    ck_assert_int_eq(wt_rtc_sensor_info(rtc, wt_rtc_nsensors(rtc), &si), WT_ERR_INVALID);
    wt_rtc_dm di;
    ck_assert_int_eq(wt_rtc_dm_info(rtc, -1, &di), WT_ERR_INVALID);
    free(s), free(a), free(b), free(sf), free(af), free(bad);
    wt_rtc_close(rtc);
    wt_rtc_close(ref);
    wt_context_free(ctx);
}
END_TEST

/* Bad input at set-up: a missing file, an unknown reconstructor, a bad key, a malformed text, an MVM
 * built for another system, a missing matrix; each names what is wrong and leaves *out NULL. */
START_TEST(test_bad_open)
{
    tu_alloc al = TU_ALLOC_INIT;
    wt_context *ctx = tu_context();
    tu_alloc_install(ctx, &al);
    wt_rtc *rtc = (wt_rtc *)ctx;
    char m[256];
    path(m, sizeof m, "M.h5");
    ck_assert_int_eq(wt_rtc_open(ctx, "pcg3", "/nonexistent/demo.cfg", 0, NULL, &rtc), WT_ERR_IO);
    ck_assert_ptr_null(rtc);
    ck_assert_msg(has(ctx, "/nonexistent/demo.cfg"), "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_open(ctx, "pcg4", DEMO, 0, NULL, &rtc), WT_ERR_INVALID);
    ck_assert(has(ctx, "'pcg4'") && has(ctx, "\"pcg3\" or \"cg9\""));
    ck_assert_int_eq(wt_rtc_open(ctx, "mvm", DEMO, 0, NULL, &rtc), WT_ERR_INVALID);
    ck_assert(has(ctx, "wt_rtc_open_mvm"));
    ck_assert_int_eq(wt_rtc_open(ctx, NULL, DEMO, 0, NULL, &rtc), WT_ERR_INVALID);
    ck_assert_int_eq(wt_rtc_open(ctx, "pcg3", NULL, 0, NULL, &rtc), WT_ERR_INVALID);
    ck_assert_int_eq(wt_rtc_open(ctx, "pcg3", DEMO, 2, NULL, &rtc), WT_ERR_INVALID);
    const char *bad_key[] = {"loop.gain=1.5"};
    ck_assert_int_eq(wt_rtc_open(ctx, "pcg3", DEMO, 1, bad_key, &rtc), WT_ERR_CONFIG);
    ck_assert_msg(has(ctx, "loop.gain"), "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_open_text(ctx, "cg9", "telescope = { diameter_m = ", 0, NULL, &rtc), WT_ERR_CONFIG);
    ck_assert_msg(has(ctx, "(configuration text)"), "%s", wt_error_message(ctx));
    /* the matrix was built for the demo as it is: another α is another system */
    const char *alpha[] = {"recon.alpha=3.0"};
    ck_assert_int_eq(wt_rtc_open_mvm(ctx, m, DEMO, 1, alpha, &rtc), WT_ERR_FORMAT);
    ck_assert_msg(has(ctx, "built for another system"), "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_open_mvm(ctx, m, NULL, 1, alpha, &rtc), WT_ERR_FORMAT);
    ck_assert(has(ctx, "built for another system"));
    /* but the loop's keys are not the matrix's: a gain override is fine */
    const char *gain[] = {"loop.gain=0.3"};
    ck_assert_msg(wt_rtc_open_mvm(ctx, m, NULL, 1, gain, &rtc) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert(wt_rtc_gain(rtc) == 0.3);
    ck_assert_str_eq(wt_rtc_recon(rtc), "mvm-pcg3");
    wt_rtc_close(rtc);
    /* prediction is in a predictive matrix's identity: this one, built without it, is another system */
    const char *pred[] = {"recon.predict=true"};
    ck_assert_int_eq(wt_rtc_open_mvm(ctx, m, NULL, 1, pred, &rtc), WT_ERR_FORMAT);
    ck_assert_msg(has(ctx, "built for another system"), "%s", wt_error_message(ctx));
    ck_assert_ptr_null(rtc);
    ck_assert_int_eq(wt_rtc_open_mvm(ctx, "/nonexistent/M.h5", NULL, 0, NULL, &rtc), WT_ERR_IO);
    ck_assert_msg(has(ctx, "/nonexistent/M.h5"), "%s", wt_error_message(ctx));
    ck_assert_ptr_null(rtc);
    /* a telemetry file is not a matrix */
    char tel[256];
    path(tel, sizeof tel, "tel.h5");
    ck_assert_int_lt(wt_rtc_open_mvm(ctx, tel, NULL, 0, NULL, &rtc), 0);
    ck_assert_msg(has(ctx, "tel.h5"), "%s", wt_error_message(ctx));
    ck_assert_int_eq(al.live, 0); /* every refusal freed what it had allocated */
    wt_context_free(ctx);
}
END_TEST

/* Set-up under allocation failure: every refused allocation surfaces as WT_ERR_NOMEM, frees what was
 * allocated, and leaves *out NULL (a budget of 0, 1, 2, … allocations until it succeeds; the first 40 and
 * then every 7th, to keep it short). */
START_TEST(test_open_out_of_memory)
{
    tu_alloc al = TU_ALLOC_INIT;
    wt_context *ctx = tu_context();
    tu_alloc_install(ctx, &al);
    char *text = read_text("tel.h5", "config");
    int ok = 0;
    for (long b = 0; b < 100000 && !ok; b += b < 40 ? 1 : 7) {
        wt_rtc *rtc = (wt_rtc *)ctx;
        tu_alloc_budget(&al, b);
        int st = wt_rtc_open_text(ctx, "pcg3", text, 0, NULL, &rtc);
        if (st == WT_OK) {
            ok = 1;
            wt_rtc_close(rtc);
        } else {
            ck_assert_msg(st == WT_ERR_NOMEM, "budget %ld: %d %s", b, st, wt_error_message(ctx));
            ck_assert_ptr_null(rtc);
        }
        ck_assert_msg(al.live == 0, "budget %ld: %ld blocks left", b, al.live);
    }
    ck_assert(ok);
    /* a share that runs out of memory (its context's) leaves nothing behind and the plan to its holder */
    wt_context *c2 = tu_context();
    wt_rtc *src = open_case(c2, 2), *rtc = NULL;
    for (long b = 0, st = WT_ERR_NOMEM; st == WT_ERR_NOMEM; b++) {
        tu_alloc_budget(&al, b);
        if ((st = wt_rtc_share(ctx, src, &rtc)) < 0) ck_assert_ptr_null(rtc);
        wt_rtc_close(rtc);
        ck_assert_int_eq(al.live, 0);
    }
    ck_assert_int_eq(wt_rtc_share(ctx, NULL, &rtc), WT_ERR_INVALID);
    ck_assert(has(ctx, "src is NULL") && !rtc);
    wt_rtc_close(src);
    wt_context_free(c2);
    free(text);
    wt_context_free(ctx);
}
END_TEST

/* Â through the API (wt_rtc_interaction): the frame's POLC term (a frame given `applied` a equals a frame on
 * s + Â a flagged WT_RTC_SLOPES_OL, bit for bit), its transpose (<Â a, s> = <a, Âᵀ s> within 1e-12
 * relative: two sums of ~10^3 products, each rounded at 1e-16), one operator whatever the instance (pcg3,
 * the MVM, "none"), and refusals naming what is wrong. "none" is the system alone: frames return zeros,
 * its configuration is the text it was opened with, read back unchanged. */
START_TEST(test_interaction)
{
    wt_context *ctx = tu_context();
    wt_rtc *p = open_case(ctx, 0), *q = open_case(ctx, 0), *mvm = open_case(ctx, 2), *none = NULL;
    char *text = read_text("tel.h5", "config");
    ck_assert_msg(wt_rtc_open_text(ctx, "none", text, 0, NULL, &none) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(wt_rtc_recon(none), "none");
    ck_assert_str_eq(wt_rtc_config(none), text);
    ck_assert_str_eq(wt_rtc_config(p), text);
    const int64_t ns = wt_rtc_nslopes(p), na = wt_rtc_nactuators(p);
    ck_assert_int_eq(wt_rtc_nslopes(none), ns);
    ck_assert_int_eq(wt_rtc_nactuators(none), na);
    double *a = malloc((size_t)na * sizeof *a), *s = malloc((size_t)ns * sizeof *s), *y = malloc((size_t)ns * sizeof *y),
           *y2 = malloc((size_t)ns * sizeof *y2), *at = malloc((size_t)na * sizeof *at),
           *c1 = malloc((size_t)na * sizeof *c1), *c2 = malloc((size_t)na * sizeof *c2);
    tu_randn(a, na, 11);
    tu_randn(s, ns, 12);
    for (int64_t i = 0; i < na; i++) a[i] *= 1e-7; /* commands [m] */
    for (int64_t i = 0; i < ns; i++) s[i] *= 1e-6; /* slopes [rad] */
    ck_assert_int_eq(wt_rtc_interaction(p, a, na, y, ns), WT_OK);
    ck_assert(tu_norm(y, ns) > 0.0);
    ck_assert_int_eq(wt_rtc_interaction(mvm, a, na, y2, ns), WT_OK);
    ck_assert(!memcmp(y, y2, (size_t)ns * sizeof *y));
    ck_assert_int_eq(wt_rtc_interaction(none, a, na, y2, ns), WT_OK);
    ck_assert(!memcmp(y, y2, (size_t)ns * sizeof *y));
    ck_assert_int_eq(wt_rtc_interaction_t(p, s, ns, at, na), WT_OK);
    const double lhs = tu_dot(y, s, ns), rhs = tu_dot(a, at, na);
    ck_assert_msg(fabs(lhs - rhs) <= 1e-12 * tu_norm(y, ns) * tu_norm(s, ns), "<Aa, s> %.17g, <a, A's> %.17g", lhs, rhs);
    /* the POLC term: R (s + Â a) from the caller equals the frame's own s_ol */
    for (int64_t i = 0; i < ns; i++) y2[i] = s[i] + y[i];
    ck_assert_int_ge(wt_rtc_frame(p, s, ns, a, WT_RTC_RAW, c1, na), 0);
    ck_assert_int_ge(wt_rtc_frame(q, y2, ns, NULL, WT_RTC_RAW | WT_RTC_SLOPES_OL, c2, na), 0);
    ck_assert(!memcmp(c1, c2, (size_t)na * sizeof *c1));
    ck_assert(tu_norm(c1, na) > 0.0);
    ck_assert_int_eq(wt_rtc_frame(none, s, ns, NULL, 0, c1, na), WT_OK);
    for (int64_t i = 0; i < na; i++) ck_assert(c1[i] == 0.0);
    /* refusals */
    ck_assert_int_eq(wt_rtc_interaction(p, a, na - 1, y, ns), WT_ERR_INVALID);
    ck_assert_msg(has(ctx, "wt_rtc_interaction") && has(ctx, "needs"), "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_interaction_t(p, s, ns, NULL, na), WT_ERR_INVALID);
    a[5] = NAN;
    ck_assert_int_eq(wt_rtc_interaction(p, a, na, y, ns), WT_ERR_NUMERIC);
    ck_assert_msg(has(ctx, "command 5 (DM 1 active actuator 5) is NaN"), "%s", wt_error_message(ctx));
    s[3] = INFINITY;
    ck_assert_int_eq(wt_rtc_interaction_t(p, s, ns, at, na), WT_ERR_NUMERIC);
    ck_assert_msg(has(ctx, "slope 3 (LGS1 s_x of valid subaperture 3) is Inf"), "%s", wt_error_message(ctx));
    free(a), free(s), free(y), free(y2), free(at), free(c1), free(c2), free(text);
    wt_rtc_close(p);
    wt_rtc_close(q);
    wt_rtc_close(mvm);
    wt_rtc_close(none);
    wt_context_free(ctx);
}
END_TEST

/* `wavetomo run`'s instance (internal open on its system, pseudo-open-loop slopes only, no Â built)
 * refuses a frame that would need Â, and runs the others. */
START_TEST(test_only_ol)
{
    wt_context *ctx = tu_context();
    wt_config *cfg;
    wt_system *sys;
    wt_rtc *rtc;
    ck_assert_int_eq(wt_config_read(ctx, DEMO, 0, NULL, &cfg), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    ck_assert_int_eq(wt_rtc_open_system(ctx, sys, WT_RECON_PCG3, NULL, 3, 1, &rtc), WT_OK);
    double *s = calloc((size_t)sys->nslopes, sizeof *s), *a = calloc((size_t)sys->nact, sizeof *a);
    ck_assert_int_eq(wt_rtc_frame(rtc, s, sys->nslopes, NULL, 0, a, sys->nact), WT_ERR_INVALID);
    ck_assert_msg(has(ctx, "pseudo-open-loop slopes only"), "%s", wt_error_message(ctx));
    ck_assert_int_ge(wt_rtc_frame(rtc, s, sys->nslopes, NULL, WT_RTC_SLOPES_OL, a, sys->nact), 0);
    ck_assert_int_ge(wt_rtc_frame(rtc, s, sys->nslopes, a, WT_RTC_SLOPES_OL | WT_RTC_RAW, a, sys->nact), 0);
    wt_rtc *bad;
    ck_assert_int_eq(wt_rtc_open_system(ctx, sys, WT_RECON_MVM, NULL, -1, 1, &bad), WT_ERR_INVALID);
    ck_assert_int_eq(wt_rtc_interaction(rtc, a, sys->nact, s, sys->nslopes), WT_ERR_INVALID);
    ck_assert_msg(has(ctx, "no Â"), "%s", wt_error_message(ctx));
    ck_assert_int_eq(wt_rtc_open_system(ctx, sys, 42, NULL, -1, 0, &bad), WT_ERR_INVALID);
    ck_assert_ptr_null(bad);
    free(s), free(a);
    wt_rtc_close(rtc);
    wt_system_free(sys);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("rtc");
    TCase *tc = tcase_create("rtc");
    tcase_set_timeout(tc, 600);
    tcase_add_unchecked_fixture(tc, files_setup, files_teardown);
    tcase_add_test(tc, test_version);
    tcase_add_loop_test(tc, test_equals_run, 0, 3);
    tcase_add_loop_test(tc, test_polc_equals_loop, 0, 14);
    tcase_add_loop_test(tc, test_no_allocation_per_frame, 0, 2);
    tcase_add_test(tc, test_reset_and_raw);
    tcase_add_test(tc, test_instances_in_threads);
    tcase_add_loop_test(tc, test_share_equals_open, 0, 3);
    tcase_add_test(tc, test_shares_in_threads);
    tcase_add_test(tc, test_orderings);
    tcase_add_test(tc, test_bad_frames);
    tcase_add_test(tc, test_bad_open);
    tcase_add_test(tc, test_open_out_of_memory);
    tcase_add_test(tc, test_interaction);
    tcase_add_test(tc, test_only_ol);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
