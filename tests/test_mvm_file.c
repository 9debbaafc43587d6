/* tests/test_mvm_file.c: MATRIX.h5 (SPEC §9): round trip, and the refusals — a matrix from another
 * configuration, a truncated file, a build killed before it finished. */
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "builder/mvm_build.h"
#include "core/io/mvm_file.h"
#include "core/la/half.h"
#include "core/model/system.h"
#include "testutil.h"

static char dir[64];

static void make_dir(void)
{
    snprintf(dir, sizeof dir, "/tmp/wt_mvmfile_XXXXXX");
    ck_assert_ptr_nonnull(mkdtemp(dir));
}

/* Build the demo pcg3 matrix for cfg. */
static wt_mvm *build(wt_context *ctx, wt_config *cfg)
{
    wt_system *sys;
    wt_mvm *m;
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    ck_assert_msg(wt_mvm_build_variant(ctx, sys, cfg, "pcg3", NULL, &m) == WT_OK, "%s", wt_error_message(ctx));
    wt_system_free(sys);
    return m;
}

/* Write m to path; commit = 0 models a build killed before its commit: the process dies right after
 * writing (only in a child process, which does no BLAS: OpenBLAS's thread pool does not survive fork). */
static void write_matrix(wt_context *ctx, const wt_mvm *m, wt_config *cfg, const char *path, int commit)
{
    wt_h5_writer *w;
    ck_assert_int_eq(wt_h5_create(ctx, path, &w), WT_OK);
    ck_assert_int_eq(wt_mvm_write(w, m, cfg, "pcg3"), WT_OK);
    if (!commit) {
        wt_h5_flush(w);
        _exit(0);
    }
    ck_assert_int_eq(wt_h5_commit(w), WT_OK);
}

START_TEST(test_round_trip_and_refusals)
{
    make_dir();
    char path[128], trunc[128];
    snprintf(path, sizeof path, "%s/M.h5", dir);
    snprintf(trunc, sizeof trunc, "%s/T.h5", dir);
    wt_context *ctx = tu_context();
    wt_config *cfg, *other;
    wt_system *sys;
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &cfg), WT_OK);
    wt_mvm *built = build(ctx, cfg);
    write_matrix(ctx, built, cfg, path, 1);
    ck_assert_int_eq(wt_system_alloc(ctx, cfg, &sys), WT_OK);
    wt_mvm *m;
    char variant[16];
    ck_assert_msg(wt_mvm_read(ctx, path, cfg, sys->nact, sys->nslopes, &m, variant) == WT_OK, "%s", wt_error_message(ctx));
    ck_assert_str_eq(variant, "pcg3");
    ck_assert_int_eq(m->nact, sys->nact);
    ck_assert_int_eq(m->nslopes, sys->nslopes);
    double norm = 0;
    for (int64_t i = 0; i < m->nact * m->nslopes; i++) norm += (double)m->R[i] * m->R[i];
    ck_assert(norm > 0 && isfinite(norm));
    /* float32 in, float32 out: the round trip is exact */
    ck_assert_int_eq(m->commands, WT_MVM_LAYER_VALUES);
    ck_assert(!memcmp(m->R, built->R, (size_t)(m->nact * m->nslopes) * sizeof *m->R));
    ck_assert(!memcmp(m->RA, built->RA, (size_t)(m->nact * m->nact) * sizeof *m->RA));
    wt_mvm_free(m);

    /* another system (α = 2): refused, naming the file and the reason */
    const char *set[] = {"recon.alpha=2.0"};
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 1, set, &other), WT_OK);
    ck_assert_int_eq(wt_mvm_read(ctx, path, other, sys->nact, sys->nslopes, &m, NULL), WT_ERR_FORMAT);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "built for another system"));
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), path));
    ck_assert_ptr_null(m);
    wt_config_free(ctx, other);
    /* a model with a controlled error is another system (the prior's r0), named in the refusal ... */
    const char *r0err[] = {"recon.atmosphere.error_r0_scale=1.2"};
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 1, r0err, &other), WT_OK);
    ck_assert_int_eq(wt_mvm_read(ctx, path, other, sys->nact, sys->nslopes, &m, NULL), WT_ERR_FORMAT);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "built for another system"));
    ck_assert_msg(strstr(wt_error_message(ctx), "recon.atmosphere.error_r0_scale = not set in the matrix, 1.2 in"), "%s",
                  wt_error_message(ctx));
    ck_assert_ptr_null(m);
    wt_config_free(ctx, other);
    /* ... but not an error of the wind, which only a predictive matrix holds (recon.predict: test_mvm_predict.c) */
    const char *winderr[] = {"recon.atmosphere.error_wind_speed_scale=1.5", "recon.atmosphere.error_wind_direction_deg=20.0"};
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 2, winderr, &other), WT_OK);
    ck_assert_msg(wt_mvm_read(ctx, path, other, sys->nact, sys->nslopes, &m, NULL) == WT_OK, "%s", wt_error_message(ctx));
    wt_mvm_free(m);

    /* truncated: refused cleanly */
    struct stat sb;
    ck_assert_int_eq(stat(path, &sb), 0);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "cp %s %s && truncate -s %lld %s", path, trunc, (long long)sb.st_size / 2, trunc);
    ck_assert_int_eq(system(cmd), 0);
    int st = wt_mvm_read(ctx, trunc, cfg, sys->nact, sys->nslopes, &m, NULL);
    ck_assert_msg(st == WT_ERR_FORMAT || st == WT_ERR_IO, "truncated file gave %d", st);
    ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), trunc));

    /* killed before the commit: no file at the target; the temporary is refused */
    char killed[128];
    snprintf(killed, sizeof killed, "%s/K.h5", dir);
    pid_t pid = fork();
    ck_assert_int_ge(pid, 0);
    if (pid == 0) write_matrix(ctx, built, cfg, killed, 0);
    int status;
    waitpid(pid, &status, 0);
    ck_assert_int_ne(access(killed, F_OK), 0);
    snprintf(cmd, sizeof cmd, "ls %s/K.h5.tmp-* >/dev/null 2>&1", dir);
    ck_assert_int_eq(system(cmd), 0); /* the half-written temporary is there … */
    snprintf(cmd, sizeof cmd, "cp %s/K.h5.tmp-* %s/K2.h5", dir, dir);
    ck_assert_int_eq(system(cmd), 0);
    snprintf(killed, sizeof killed, "%s/K2.h5", dir);
    ck_assert_int_eq(wt_mvm_read(ctx, killed, cfg, sys->nact, sys->nslopes, &m, NULL), WT_ERR_FORMAT); /* … and never passes */
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    ck_assert_int_eq(system(cmd), 0);
    wt_mvm_free(built);
    wt_system_free(sys);
    wt_config_free(ctx, other);
    wt_config_free(ctx, cfg);
    wt_context_free(ctx);
}
END_TEST

/* recon.mvm_precision fp16 / bf16: built, written as 16-bit floats, read back bit for bit, also under
 * the fp32 configuration (the precision is how R is stored, not which system it is for: not hashed);
 * a file claiming another precision is refused; the apply agrees with the fp32 matrix within half.h's
 * bound. */
START_TEST(test_half_round_trip)
{
    make_dir();
    char path[128];
    snprintf(path, sizeof path, "%s/H.h5", dir);
    wt_context *ctx = tu_context();
    wt_config *c32, *c16;
    wt_system *sys;
    const char *names[2] = {"recon.mvm_precision=\"fp16\"", "recon.mvm_precision=\"bf16\""};
    ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 0, NULL, &c32), WT_OK);
    ck_assert_int_eq(wt_system_alloc(ctx, c32, &sys), WT_OK);
    wt_mvm *m32 = build(ctx, c32);
    ck_assert_int_eq(m32->precision, WT_PREC_F32);
    for (int p = 0; p < 2; p++) {
        ck_assert_int_eq(wt_config_read(ctx, "data/presets/demo.cfg", 1, &names[p], &c16), WT_OK);
        ck_assert_int_eq(c16->mvm_precision, p == 0 ? WT_PREC_F16 : WT_PREC_BF16);
        ck_assert_str_eq(c16->matrix_sha256, c32->matrix_sha256);
        wt_mvm *built = build(ctx, c16), *m = NULL;
        ck_assert_int_eq(built->precision, c16->mvm_precision);
        write_matrix(ctx, built, c16, path, 1);
        ck_assert_msg(wt_mvm_read(ctx, path, c32, sys->nact, sys->nslopes, &m, NULL) == WT_OK, "%s", wt_error_message(ctx));
        ck_assert_int_eq(m->precision, c16->mvm_precision);
        ck_assert_ptr_null(m->R);
        const size_t nr = (size_t)(m->nact * m->nslopes), na = (size_t)(m->nact * m->nact);
        ck_assert(!memcmp(m->Rh, built->Rh, nr * sizeof *m->Rh));
        ck_assert(!memcmp(m->RAh, built->RAh, na * sizeof *m->RAh));
        ck_assert(!memcmp(m->Rc, built->Rc, (size_t)m->nact * sizeof *m->Rc));
        ck_assert(!memcmp(m->RAc, built->RAc, (size_t)m->nact * sizeof *m->RAc));
        wt_mvm_free(m);
        m = NULL;
        /* the stored element type must be the one the precision names: an fp32 file read as fp16
         * (what a file relabelled by hand would ask for) is refused naming the dataset and both types */
        if (p == 0) {
            char f32[160];
            snprintf(f32, sizeof f32, "%s/f32.h5", dir);
            write_matrix(ctx, m32, c32, f32, 1);
            wt_mvm_file_data d = {WT_MVM_FILE_F16, NULL, NULL, malloc(nr * 2), malloc(na * 2),
                                  malloc((size_t)sys->nact * 4), malloc((size_t)sys->nact * 4)};
            const wt_mvm_file_system fs = {.sha256 = c32->matrix_sha256, .text = c32->matrix_text, .path = c32->path};
            ck_assert_int_eq(wt_mvm_file_read(ctx, f32, &fs, sys->nact, sys->nslopes, &d, NULL), WT_ERR_FORMAT);
            ck_assert_ptr_nonnull(strstr(wt_error_message(ctx), "'R' is float32, refused as float16"));
            free(d.Rh), free(d.RAh), free(d.Rc), free(d.RAc);
        }
        /* same slopes through both: |Δy_i| ≤ (u + float32 sums) Σ_j |R_ij s_j| */
        float *s = malloc(sizeof(float) * (size_t)sys->nslopes), *y32 = malloc(sizeof(float) * (size_t)sys->nact),
              *y16 = malloc(sizeof(float) * (size_t)sys->nact);
        for (int64_t j = 0; j < sys->nslopes; j++) s[j] = (float)(1e-6 * sin(0.37 * (double)j));
        wt_mvm_apply(m32, s, NULL, y32);
        wt_mvm_apply(built, s, NULL, y16);
        const double u = p == 0 ? 0x1p-11 : 0x1p-8;
        for (int64_t i = 0; i < sys->nact; i++) {
            double sabs = 0;
            for (int64_t j = 0; j < sys->nslopes; j++) sabs += fabs((double)m32->R[i * sys->nslopes + j] * s[j]);
            ck_assert_msg(fabs((double)y16[i] - y32[i]) <= (u + 1e-4) * sabs, "actuator %lld", (long long)i);
        }
        free(s);
        free(y32);
        free(y16);
        wt_mvm_free(built);
        wt_config_free(ctx, c16);
    }
    char cmd[160];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    ck_assert_int_eq(system(cmd), 0);
    wt_mvm_free(m32);
    wt_system_free(sys);
    wt_config_free(ctx, c32);
    wt_context_free(ctx);
}
END_TEST

/* The keys two canonical texts disagree on, named with both values (nested groups as dotted paths, a key
 * one text lacks as "not set", at most three, then a count); nothing for equal texts, a NULL one, or a text
 * longer than the limit (a corrupt file's). */
START_TEST(test_text_diff)
{
    const char *a = "telescope = {\n  diameter_m = 8.0;\n};\nrecon = {\n  alpha = 1.0;\n  pcg3 = {\n"
                    "    layer_size = [ 32, 16, 32 ];\n  };\n  tau = 0.8;\n};\n";
    const char *b = "telescope = {\n  diameter_m = 8.0;\n};\nrecon = {\n  alpha = 0.5;\n  pcg3 = {\n"
                    "    layer_size = [ 32, 32, 32 ];\n  };\n  tau = 0.8;\n  model_error = true;\n};\n";
    char buf[512];
    wt_mvm_file_text_diff(a, a, "A", "B", buf, sizeof buf);
    ck_assert_str_eq(buf, "");
    wt_mvm_file_text_diff(a, NULL, "A", "B", buf, sizeof buf);
    ck_assert_str_eq(buf, "");
    wt_mvm_file_text_diff(a, b, "A", "B", buf, sizeof buf);
    ck_assert_str_eq(buf, "recon.alpha = 1.0 in A, 0.5 in B; recon.pcg3.layer_size = [ 32, 16, 32 ] in A, [ 32, 32, 32 ] "
                          "in B; recon.model_error = not set in A, true in B");
    const char *c = "recon = {\n  alpha = 2.0;\n  tau = 0.5;\n};\nloop = {\n  gain = 0.3;\n};\n";
    wt_mvm_file_text_diff(b, c, "A", "B", buf, sizeof buf);
    ck_assert_msg(strstr(buf, "telescope.diameter_m = 8.0 in A, not set in B; recon.alpha = 0.5 in A, 2.0 in B; ") == buf,
                  "%s", buf);
    ck_assert_msg(strstr(buf, "; and 3 more keys"), "%s", buf); /* recon.tau, recon.model_error, loop.gain */
    char small[16];
    wt_mvm_file_text_diff(a, b, "A", "B", small, sizeof small); /* truncated, terminated */
    ck_assert_int_eq(strlen(small), sizeof small - 1);
    char *big = malloc(WT_MVM_FILE_DIFF_MAX_TEXT + 2);
    memset(big, 'x', WT_MVM_FILE_DIFF_MAX_TEXT + 1);
    big[WT_MVM_FILE_DIFF_MAX_TEXT + 1] = '\0';
    wt_mvm_file_text_diff(a, big, "A", "B", buf, sizeof buf);
    ck_assert_str_eq(buf, "");
    free(big);
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("mvm_file");
    TCase *tc = tcase_create("io");
    tcase_set_timeout(tc, 120);
    tcase_add_test(tc, test_round_trip_and_refusals);
    tcase_add_test(tc, test_half_round_trip);
    tcase_add_test(tc, test_text_diff);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
