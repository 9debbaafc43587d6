/* tests/test_install.c: `make install` as a user of the C library meets it. make test installs into a
 * temporary DESTDIR (WT_INSTALL_DESTDIR, prefix WT_INSTALL_PREFIX; without them this suite runs the
 * install itself); the suite checks the tree (soname links, public headers only, pkg-config file, man
 * page, presets and the data they read), that the shared library exports exactly the public headers'
 * functions, builds programs against the installed copy from clean directories with
 * `pkg-config --cflags --libs wavetomo` (shared, and static from Libs.private / Requires.private) and runs
 * them, runs examples/rtc_loop.c on telemetry made by the installed executable from the installed
 * presets (its commands equal `wavetomo run`'s), imports the installed Python package with nothing but the
 * tree to find the library and executable by, and finally `make uninstall` leaves nothing behind.
 * WT_INSTALL_CFLAGS: flags the programs are built with too (the sanitizers of a make debug-test build). */
#include <stdarg.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testutil.h"
#include "wavetomo/version.h"

static char dest[256], prefix[128], root[512], work[64], env[4096];

/* Run a shell command (with the pkg-config and loader environment of the installed tree); its output
 * goes to work/out.txt. Returns the exit status. */
static int sh(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int sh(const char *fmt, ...)
{
    char cmd[16384];
    va_list ap;
    int n = snprintf(cmd, sizeof cmd, "%s; cd %s && { ", env, work);
    va_start(ap, fmt);
    n += vsnprintf(cmd + n, sizeof cmd - (size_t)n, fmt, ap);
    va_end(ap);
    snprintf(cmd + n, sizeof cmd - (size_t)n, "; } > %s/out.txt 2>&1", work);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static char out_text[65536];
static const char *out(void)
{
    char p[128];
    snprintf(p, sizeof p, "%s/out.txt", work);
    FILE *f = fopen(p, "r");
    out_text[0] = 0;
    if (f) {
        size_t k = fread(out_text, 1, sizeof out_text - 1, f);
        out_text[k] = 0;
        fclose(f);
    }
    return out_text;
}

#define SH_OK(...) ck_assert_msg(sh(__VA_ARGS__) == 0, "%s", out())

/* The make that runs uninstall (and install when make test did not): without the parent make's job
 * server, which a suite run from make does not get. */
#define MAKE "env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make --no-print-directory -s -C"

static void setup(void)
{
    ck_assert_ptr_nonnull(getcwd(root, sizeof root));
    snprintf(work, sizeof work, "/tmp/wt-install-testXXXXXX");
    ck_assert_ptr_nonnull(mkdtemp(work));
    const char *d = getenv("WT_INSTALL_DESTDIR"), *p = getenv("WT_INSTALL_PREFIX");
    snprintf(prefix, sizeof prefix, "%s", p ? p : "/usr/local");
    if (d) {
        snprintf(dest, sizeof dest, "%s", d);
    } else { /* run alone: install here */
        snprintf(dest, sizeof dest, "%s/destdir", work);
        char icmd[2048];
        snprintf(icmd, sizeof icmd, MAKE " %s install DESTDIR=%s PREFIX=%s > %s/install.txt 2>&1", root, dest, prefix, work);
        ck_assert_msg(system(icmd) == 0, "make install failed: see %s/install.txt", work);
    }
    /* pkg-config reads the installed file with its prefix line pointing into the DESTDIR, as a relocated
     * tree would (a sysroot, or --define-prefix, would move the dependencies' -I and -L as well); the
     * loader finds the installed library; the presets are the installed ones */
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "mkdir %1$s/pc && sed 's|^prefix=.*|prefix=%2$s%3$s|' %2$s%3$s/lib/pkgconfig/wavetomo.pc "
             "> %1$s/pc/wavetomo.pc", work, dest, prefix);
    ck_assert_int_eq(system(cmd), 0);
    snprintf(env, sizeof env,
             "export PKG_CONFIG_PATH=%3$s/pc LD_LIBRARY_PATH=%1$s%2$s/lib "
             "OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 WT=%1$s%2$s/bin/wavetomo SHARE=%1$s%2$s/share/wavetomo SRC=%4$s",
             dest, prefix, work, root);
}

static void teardown(void) { tu_cli_teardown(work); }

/* The tree: what is installed, and nothing internal among the headers. */
START_TEST(test_tree)
{
    const char *files[] = {"bin/wavetomo", "lib/libwavetomo.a", "lib/pkgconfig/wavetomo.pc",
                           "include/wavetomo/wavetomo.h", "include/wavetomo/version.h", "include/wavetomo/context.h",
                           "include/wavetomo/rtc.h", "share/man/man1/wavetomo.1", "share/wavetomo/presets/demo.cfg",
                           "share/wavetomo/presets/eelt-mcao.cfg", "share/wavetomo/presets/demo-diffractive.cfg",
                           "share/wavetomo/sodium/default.txt", "share/wavetomo/atmosphere/eso35-median.txt",
                           "share/wavetomo/presets/eelt-mcao-eso35.cfg", "share/wavetomo/nights/demo-ground-doubling.txt",
                           "share/wavetomo/nights/eso35-ground-doubling.txt", "share/wavetomo/presets/demo-night.cfg",
                           "share/wavetomo/presets/eelt-mcao-night.cfg", "share/doc/wavetomo/c-api.md",
                           "share/doc/wavetomo/examples/rtc_loop.c", "share/doc/wavetomo/examples/my-system.cfg"};
    char p[1024];
    for (size_t i = 0; i < sizeof files / sizeof *files; i++) {
        snprintf(p, sizeof p, "%s%s/%s", dest, prefix, files[i]);
        ck_assert_msg(access(p, R_OK) == 0, "%s is missing", p);
    }
    snprintf(p, sizeof p, "%s%s/bin/wavetomo", dest, prefix);
    ck_assert(access(p, X_OK) == 0);
    /* the real file, its soname link, the development link */
    char so[64], soname[64];
    snprintf(so, sizeof so, "libwavetomo.so.%s", WT_VERSION_STRING);
    snprintf(soname, sizeof soname, "libwavetomo.so.%d", WT_VERSION_MAJOR);
    SH_OK("test -f $SHARE/../../lib/%s && test ! -L $SHARE/../../lib/%s && "
          "test \"$(readlink $SHARE/../../lib/%s)\" = %s && test \"$(readlink $SHARE/../../lib/libwavetomo.so)\" = %s",
          so, so, soname, so, soname);
    SH_OK("objdump -p $SHARE/../../lib/%s | grep SONAME", so);
    ck_assert_msg(strstr(out(), soname), "soname: %s", out());
    /* exactly the public headers */
    SH_OK("ls $SHARE/../../include/wavetomo | tr '\\n' ' '");
    ck_assert_str_eq(out(), "context.h rtc.h version.h wavetomo.h ");
    /* the installed presets read, the diffractive one finds its sodium profile next to them, the ESO one its
     * atmosphere profile and the night one its night (read when the loop is set up: two frames) */
    SH_OK("for f in $SHARE/presets/*.cfg; do $WT sim --config $f --out x.h5 --dry-run > /dev/null || exit 1; done && "
          "$WT info $SHARE/presets/demo-diffractive.cfg --no-nnz > /dev/null && "
          "$WT sim --config $SHARE/presets/demo-night.cfg --frames 2 --set evaluation.settle_frames=0 --out n.h5 "
          "--quiet > /dev/null");
    /* the man page: every command's section, the version, and groff finds nothing to warn about */
    SH_OK("cat $SHARE/../man/man1/wavetomo.1");
    ck_assert(strstr(out(), ".TH WAVETOMO 1") && strstr(out(), "wavetomo " WT_VERSION_STRING));
    const char *cmds[] = {"info", "sim", "build", "run", "compare", "budget", "bench"};
    for (int i = 0; i < 7; i++) {
        snprintf(p, sizeof p, ".SS \"wavetomo %s\"", cmds[i]);
        ck_assert_msg(strstr(out(), p), "man page lacks %s", p);
    }
    if (system("command -v groff > /dev/null") == 0) {
        SH_OK("groff -k -man -Tutf8 -ww -z $SHARE/../man/man1/wavetomo.1 2>&1 | head -5 | tee /dev/stderr | wc -l");
        ck_assert_msg(!strcmp(out(), "0\n"), "groff warnings: %s", out());
    }
}
END_TEST

/* The shared library exports exactly the functions the public headers declare (the rest of the library
 * is internal: core/wavetomo.map). */
START_TEST(test_exports)
{
    SH_OK("nm -D --defined-only $SHARE/../../lib/libwavetomo.so | awk '$2 == \"T\" {sub(/@.*/, \"\", $3); print $3}' "
          "| sort > exported.txt && "
          "cc -E -P -I$SHARE/../../include $SHARE/../../include/wavetomo/wavetomo.h | grep -oE '\\bwt_[a-z0-9_]+ *\\(' "
          "| tr -d ' (' | sort -u > declared.txt && diff declared.txt exported.txt && wc -l < exported.txt");
    ck_assert_msg(atoi(out()) >= 30, "%s functions exported", out());
}
END_TEST

/* A small program, built from a clean directory against the installed copy with pkg-config, runs: the
 * shared library (found by LD_LIBRARY_PATH), and the static one with Libs.private / Requires.private. */
static const char *hello =
    "#include <stdio.h>\n"
    "#include <string.h>\n"
    "#include <wavetomo/wavetomo.h>\n"
    "int main(int argc, char **argv) {\n"
    "    if (argc != 2 || strcmp(wt_version(), WT_VERSION_STRING)) return 3;\n"
    "    wt_context *ctx = wt_context_alloc();\n"
    "    wt_rtc *rtc;\n"
    "    const char *set[] = {\"loop.gain=0.5\"};\n"
    "    if (wt_rtc_open(ctx, \"pcg3\", argv[1], 1, set, &rtc) < 0) {\n"
    "        fprintf(stderr, \"%s\\n\", wt_error_message(ctx));\n"
    "        return 1;\n"
    "    }\n"
    "    static double s[100000], a[100000];\n"
    "    int st = wt_rtc_frame(rtc, s, wt_rtc_nslopes(rtc), NULL, 0, a, wt_rtc_nactuators(rtc));\n"
    "    printf(\"wavetomo %s: %s, %lld slopes, %lld commands, gain %g, status %d, command 0 = %g\\n\", wt_version(),\n"
    "           wt_rtc_recon(rtc), (long long)wt_rtc_nslopes(rtc), (long long)wt_rtc_nactuators(rtc), wt_rtc_gain(rtc),\n"
    "           st, a[0]);\n"
    "    wt_rtc_close(rtc);\n"
    "    wt_context_free(ctx);\n"
    "    return st < 0;\n"
    "}\n";

START_TEST(test_build_against_install)
{
    char p[512];
    snprintf(p, sizeof p, "%s/hello.c", work);
    FILE *f = fopen(p, "w");
    ck_assert_ptr_nonnull(f);
    fputs(hello, f);
    fclose(f);
    SH_OK("test \"$(pkg-config --modversion wavetomo)\" = " WT_VERSION_STRING);
    SH_OK("cc $WT_INSTALL_CFLAGS -std=c11 -Wall -Wextra -Werror -pedantic hello.c $(pkg-config --cflags --libs wavetomo) -o hello");
    SH_OK("ldd ./hello | grep libwavetomo");
    ck_assert_msg(strstr(out(), dest), "hello does not load the installed library: %s", out());
    SH_OK("pkg-config --variable=pkgdatadir wavetomo");
    snprintf(p, sizeof p, "%s%s/share/wavetomo\n", dest, prefix);
    ck_assert_str_eq(out(), p);
    SH_OK("./hello $(pkg-config --variable=pkgdatadir wavetomo)/presets/demo.cfg");
    ck_assert_msg(strstr(out(), "wavetomo " WT_VERSION_STRING ": pcg3, 1548 slopes") && strstr(out(), "gain 0.5, status 0"),
                  "%s", out());
    /* static: the archive and the private dependencies of the .pc file; runs without the library's .so */
    SH_OK("cc $WT_INSTALL_CFLAGS -std=c11 hello.c $(pkg-config --cflags wavetomo) -o hello-static $SHARE/../../lib/libwavetomo.a "
          "$(pkg-config --static --libs wavetomo | sed 's/-lwavetomo\\b//') && ! ldd ./hello-static | grep libwavetomo && "
          "env -u LD_LIBRARY_PATH ./hello-static $SHARE/presets/demo.cfg");
    ck_assert_msg(strstr(out(), "status 0"), "%s", out());
}
END_TEST

/* examples/rtc_loop.c against the installed library, on telemetry of the installed executable and
 * presets: its commands are `wavetomo run`'s, bit for bit (pcg3, cg9, the MVM). */
START_TEST(test_example_rtc_loop)
{
    SH_OK("cp $SHARE/../doc/wavetomo/examples/rtc_loop.c . && "
          "cc $WT_INSTALL_CFLAGS -std=c11 -Wall -Wextra -Werror rtc_loop.c $(pkg-config --cflags --libs wavetomo hdf5) -o rtc_loop");
    const char *q = "--threads 1 --quiet > /dev/null";
    SH_OK("$WT sim --config $SHARE/presets/demo.cfg --frames 6 --out r.h5 --telemetry tel.h5 %s && "
          "$WT run --recon pcg3 --telemetry tel.h5 --out c-pcg3.h5 %s && "
          "$WT run --recon cg9 --telemetry tel.h5 --out c-cg9.h5 %s && "
          "$WT build --config $SHARE/presets/demo.cfg --out M.h5 %s && "
          "$WT sim --config $SHARE/presets/demo.cfg --frames 6 --recon mvm --matrix M.h5 --out rm.h5 --telemetry tm.h5 %s && "
          "$WT run --matrix M.h5 --telemetry tm.h5 --out c-mvm.h5 %s",
          q, q, q, q, q, q);
    SH_OK("./rtc_loop tel.h5 c-pcg3.h5 pcg3 && ./rtc_loop tel.h5 c-cg9.h5 cg9 && ./rtc_loop tm.h5 c-mvm.h5 M.h5");
    ck_assert_msg(strstr(out(), "pcg3, 6 frames of 1548 slopes") && strstr(out(), "cg9, 6 frames") &&
                      strstr(out(), "mvm-pcg3, 6 frames"),
                  "%s", out());
    /* and it tells when they differ: the pcg3 telemetry replayed through cg9 */
    ck_assert_int_eq(sh("./rtc_loop tel.h5 c-pcg3.h5 cg9"), 1);
    ck_assert_msg(strstr(out(), "DIFFERENT"), "%s", out());
}
END_TEST

/* The installed Python package (by pip: its metadata and py.typed are there), imported by Debian's
 * interpreter from the installed tree alone (no LD_LIBRARY_PATH, no WAVETOMO_LIB / WAVETOMO_BIN, from a clean
 * directory): it finds the installed library and executable relative to itself, opens a reconstructor on an
 * installed preset and runs a sim. */
START_TEST(test_python_against_install)
{
    SH_OK("ls -d %s%s/lib/python3*/dist-packages/wavetomo/__init__.py %s%s/lib/python3*/dist-packages/wavetomo/py.typed "
          "%s%s/lib/python3*/dist-packages/wavetomo-" WT_VERSION_STRING ".dist-info/RECORD "
          "%s%s/share/doc/wavetomo/python-api.md", dest, prefix, dest, prefix, dest, prefix, dest, prefix);
    SH_OK("env -u LD_LIBRARY_PATH -u WAVETOMO_LIB -u WAVETOMO_BIN PYTHONDONTWRITEBYTECODE=1 "
          "PYTHONPATH=\"$(echo %s%s/lib/python3*/dist-packages)\" /usr/bin/python3 -c '"
          "import wavetomo, numpy as np\n"
          "rec = wavetomo.Reconstructor(\"'$SHARE'/presets/demo.cfg\", \"pcg3\", set={\"loop.gain\": 0.5})\n"
          "a = rec(np.zeros(rec.nslopes, np.float32))\n"
          "res = wavetomo.sim(\"'$SHARE'/presets/demo.cfg\", frames=2, threads=1)\n"
          "print(wavetomo.version(), wavetomo.library_path(), wavetomo.executable(), rec.recon, rec.nslopes, rec.gain,\n"
          "      a.dtype, res[\"frames\"], res.attrs[\"wavetomo_version\"])'",
          dest, prefix);
    char want[1024];
    snprintf(want, sizeof want, WT_VERSION_STRING " %s%s/lib/libwavetomo.so." WT_VERSION_STRING " %s%s/bin/wavetomo "
             "pcg3 1548 0.5 float32 2 " WT_VERSION_STRING "\n", dest, prefix, dest, prefix);
    ck_assert_str_eq(out(), want);
}
END_TEST

/* make uninstall removes everything make install put there (last: it empties the tree). */
START_TEST(test_uninstall)
{
    SH_OK(MAKE " $SRC uninstall DESTDIR=%s PREFIX=%s && find %s%s -type f -o -type l", dest, prefix, dest, prefix);
    ck_assert_msg(out()[0] == 0, "left behind: %s", out());
}
END_TEST

Suite *make_suite(void)
{
    Suite *s = suite_create("install");
    TCase *tc = tcase_create("install");
    tcase_set_timeout(tc, 600);
    tcase_add_unchecked_fixture(tc, setup, teardown);
    tcase_add_test(tc, test_tree);
    tcase_add_test(tc, test_exports);
    tcase_add_test(tc, test_build_against_install);
    tcase_add_test(tc, test_example_rtc_loop);
    tcase_add_test(tc, test_python_against_install);
    tcase_add_test(tc, test_uninstall);
    suite_add_tcase(s, tc);
    return s;
}

TU_MAIN
