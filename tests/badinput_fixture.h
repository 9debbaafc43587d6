/* tests/badinput_fixture.h: what the bad-input suites share (test_badinput.c, test_badinput_process.c): the
 * scratch directory and binary of each test (setup, teardown), writing a small file, and running the command
 * line with its stderr kept. */
#ifndef WT_TESTS_BADINPUT_FIXTURE_H
#define WT_TESTS_BADINPUT_FIXTURE_H

#include <fcntl.h>
#include <signal.h>
#include <stdarg.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <hdf5.h>

#include "core/config/config.h"
#include "core/io/h5.h"
#include "core/model/system.h"
#include "testutil.h"

#define DEMO "data/presets/demo.cfg"

static char dir[64], wt[512];

static void setup(void) { tu_cli_setup(wt, sizeof wt, dir, sizeof dir, "wt_bad_"); }
static void teardown(void) { tu_cli_teardown(dir); }

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    ck_assert_ptr_nonnull(f);
    fputs(text, f);
    ck_assert_int_eq(fclose(f), 0);
}

/* Run `wavetomo ARGS` (%1$s in args = the scratch directory); returns the exit code, stderr in err. */
static int run_cli(const char *args, char *err, size_t n)
{
    char cmd[4096], a[2048], ep[128];
    snprintf(a, sizeof a, args, dir, dir, dir);
    snprintf(ep, sizeof ep, "%s/stderr.txt", dir);
    snprintf(cmd, sizeof cmd, "%s %s > /dev/null 2> %s", wt, a, ep);
    int st = system(cmd);
    FILE *f = fopen(ep, "r");
    size_t k = f ? fread(err, 1, n - 1, f) : 0;
    err[k] = '\0';
    if (f) fclose(f);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

#endif
